// Reading and writing shapes: PLY (ascii, binary LE/BE), PCD (ascii, binary,
// binary_compressed), OBJ, ASCII XYZ/TXT point lists, OFF and STL (ascii, binary), with errors
// that name the file and the problem.
#pragma once

#include <Eigen/Geometry>
#include <functional>
#include <stdexcept>
#include <string>
#include <string_view>
#include <vector>

#include "hgdeform/io/shape.h"

namespace hgd {

/// Every I/O failure. what() reads "<path>: <problem>", e.g.
/// "scan.pcd: truncated data: header declares 307200 points, file holds 1024".
class IoError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

/// The format named by a path's extension (case-insensitive .ply/.pcd/.obj/.xyz/.txt/.off/
/// .stl); throws IoError naming the path for any other extension.
FileFormat formatFromPath(const std::string& path);

/// The format of a file's content (PLY magic, a PCD header, an OFF header, an ascii or binary
/// STL, OBJ 'v' lines, rows of numbers), whatever its name; throws IoError naming the file
/// when it cannot be read or its content matches no format.
FileFormat sniffFormat(const std::string& path);

/// What a shape file's header says of its size, read without its data (probeShapeSize).
struct ShapeSize {
  FileFormat format = FileFormat::Ply;
  std::uint64_t file_bytes = 0;
  /// Points: the header's count (PLY, PCD, LAS, OFF: `exact`), else an upper estimate from the
  /// file's size (text rows of at least 24 bytes; STL: three a triangle). 0 when unknown.
  std::uint64_t points = 0;
  bool exact = false;
  /// The bytes of a point's record in the file (text: 24, the three doubles its values are
  /// read as; LAS: its record, whose coordinates the reader holds as doubles).
  std::uint64_t record_bytes = 0;
  std::uint64_t faces = 0;  ///< faces the header declares (PLY, OFF) or STL's triangles
  bool binary = false;      ///< records of a fixed size (binary PLY and PCD, LAS, binary STL)
  bool compressed = false;  ///< PCD binary_compressed
};

/// Reads a shape file's header only (the format by content, as readShape). Never says what is
/// wrong with a file: when it cannot be opened, matches no format, has a malformed header or a
/// count its data cannot hold, the size is unknown (points 0) and readShape says what is wrong.
ShapeSize probeShapeSize(const std::string& path);

/// Reads a shape file. The format is the content's (sniffFormat): when the extension names
/// another format, or none, the shape's `warnings` say which format the content was read as.
/// One exception: a binary STL is known by its size alone, so a file named for a text format
/// whose size happens to fit one stays text when its text names that format or its bytes after
/// the would-be 84-byte header are all text.
/// Throws IoError when the file is missing, unreadable, empty, matches no format, has a
/// malformed header, truncated or non-numeric data, no points, or no x/y/z fields. Sizes
/// declared in headers are checked against the file's size before anything is allocated.
Shape readShape(const std::string& path);

/// Options for writeShape.
struct WriteOptions {
  Encoding encoding = Encoding::Binary;
};

/// Writes a shape as PLY, PCD, OBJ, XYZ/TXT, PTS, LAS, OFF or STL (by the extension of `path`; XYZ, OFF
/// and OBJ are text whatever the encoding; STL needs faces), atomically: the data goes
/// to a temporary file in the same directory which is renamed over `path` only when complete.
/// Refuses (IoError) to write over `shape.path`, the file the shape was read from.
/// A shape read from another format than the target's gets the field names the target's
/// readers (PCL, Open3D, MeshLab, CloudCompare) expect: PLY nx/ny/nz and uchar
/// red/green/blue(/alpha), PCD normal_x/normal_y/normal_z and a packed rgb (float, alpha 255)
/// or rgba (uint32), intensity and curvature (from scalar_intensity, scalar_curvature too);
/// a packed colour is written as red/green/blue(/alpha) in XYZ, OBJ and OFF. A shape written
/// in its own format is written as it was read.
void writeShape(const std::string& path, const Shape& shape, const WriteOptions& options = {});

/// What writing `shape` in `format` would lose, as a warning to print (every loss, joined
/// with "; "); "" when nothing is lost. What its file held beyond points and faces (FileExtras:
/// an OBJ's texture coordinates and groups, a PLY's other elements); a mesh's faces in PCD or
/// XYZ; the per-point fields STL, OFF and OBJ cannot hold (STL: all but x/y/z; OFF: all but
/// x/y/z, normals and red/green/blue/alpha; OBJ: all but x/y/z and red/green/blue), a packed
/// rgb/rgba counting as the red/green/blue it is written as. A shape is written back whole in
/// its own format.
std::string extrasLost(const Shape& shape, FileFormat format);

/// Writes bytes to `path` the same way: temporary file in the same directory, then rename.
/// Throws IoError naming the path. Every writer here treats special paths alike: a symbolic
/// link is followed (the file it names is replaced atomically, the link stays); a FIFO or a
/// device is written to directly; a path that names a descriptor (/dev/stdout, /dev/stderr,
/// /dev/fd/N, /proc/self/fd/N, also through links) is written to that descriptor, whatever it
/// is open on (a file stdout was redirected to is appended to, never replaced).
void writeFileAtomically(const std::string& path, std::string_view bytes);

/// Whether two paths name the same file, however spelt (links, hard links, "..", relative);
/// for paths that do not exist yet, whether they resolve to the same place.
bool samePath(const std::string& a, const std::string& b);

/// The one check every tool makes before it writes an output: throws IoError
/// "<output>: refusing to overwrite the input <input>" when `output` names one of `inputs`.
void refuseInputs(const std::string& output, const std::vector<std::string>& inputs);

/// Removes an output a failed run wrote (a regular file, or the file a link names; never a
/// FIFO, a device or what a descriptor path such as /dev/stdout leads to). For "a failed run
/// leaves no output".
void removeOutput(const std::string& path) noexcept;

/// Keeps the file an output is about to replace, so that a run that fails after writing its
/// output (its report cannot be written) leaves the previous one as it was. Construct before
/// writing: a regular file at `path` (or the file a link there names) is hard-linked aside as
/// `.NAME.tmp-PID-HEX` (removed on SIGINT/SIGTERM like a write in progress, and by `batch` when
/// its process is gone). restore() puts it back, or removes what was written where nothing was;
/// keep() (or the destructor) drops the copy and keeps the new output.
class PreviousOutput {
 public:
  explicit PreviousOutput(std::string path);
  ~PreviousOutput();
  PreviousOutput(const PreviousOutput&) = delete;
  PreviousOutput& operator=(const PreviousOutput&) = delete;
  void restore() noexcept;
  void keep() noexcept;

 private:
  std::string path_, target_, aside_;
  int slot_ = -1;
};

/// Removes the temporary files of writes in progress (in any thread). Async-signal-safe: a
/// SIGINT/SIGTERM handler calls it before exiting so that an interrupted run leaves no
/// partial file behind.
void removeTemporaryFiles() noexcept;

/// An OBJ's own normals ('vn', indexed apart from the vertices) turned with the shape: each by
/// the rotation `turn` gives for the vertex a face pairs it with (FileExtras::obj_normal_vertex),
/// into `extras.obj_normals_out`; those whose vertex `turn` declines (returns false), and all
/// when `turn` is empty, are kept as read.
void turnObjNormals(FileExtras& extras,
                    const std::function<bool(int vertex, Eigen::Quaterniond& rotation)>& turn);

}  // namespace hgd
