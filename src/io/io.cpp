// The public entry points: a shape's format from its path or its content, and reading and
// writing a shape in any of the formats.
#include <algorithm>
#include <cstring>
#include <filesystem>
#include <optional>

#include "io/internal.h"

namespace hgd {

using namespace io_internal;
namespace fs = std::filesystem;

namespace {

const char* formatName(FileFormat f) {
  switch (f) {
    case FileFormat::Ply: return "PLY";
    case FileFormat::Pcd: return "PCD";
    case FileFormat::Obj: return "OBJ";
    case FileFormat::Xyz: return "XYZ";
    case FileFormat::Off: return "OFF";
    case FileFormat::Stl: return "STL";
    case FileFormat::Pts: return "PTS";
    case FileFormat::Las: return "LAS";
  }
  return "?";
}

std::optional<FileFormat> formatOfExtension(const std::string& ext) {
  if (ext == ".ply") return FileFormat::Ply;
  if (ext == ".pcd") return FileFormat::Pcd;
  if (ext == ".obj") return FileFormat::Obj;
  if (ext == ".xyz" || ext == ".txt") return FileFormat::Xyz;
  if (ext == ".off") return FileFormat::Off;
  if (ext == ".stl") return FileFormat::Stl;
  if (ext == ".pts") return FileFormat::Pts;
  if (ext == ".las" || ext == ".laz") return FileFormat::Las;
  return std::nullopt;
}

bool isOffKeyword(std::string_view w) {
  return w == "OFF" || w == "COFF" || w == "NOFF" || w == "CNOFF" || w == "NCOFF";
}

/// Whether every value of a row (split at blanks and commas) is a number, and how many.
std::size_t numericColumns(std::string_view line) {
  const std::vector<std::string_view> words = splitColumns(line);
  for (const auto w : words) {
    double d = 0;
    if (!parseFloating(w, &d)) return 0;
  }
  return words.size();
}

/// Whether the file's size is that of a binary STL with the triangle count in its bytes 80-83
/// (an 80-byte header, the count, 50 bytes per triangle, nothing else).
bool sizeOfBinaryStl(std::string_view head, std::uint64_t size) {
  if (size < 84 || head.size() < 84) return false;
  return binaryStlSizeFits(reinterpret_cast<const unsigned char*>(head.data()) + 80, size);
}

/// Whether a byte is text as a text format has it (printable ASCII or a blank).
bool isTextByte(char ch) {
  const auto c = static_cast<unsigned char>(ch);
  return (c >= 0x20 && c < 0x7f) || c == '\n' || c == '\r' || c == '\t';
}

/// Whether the bytes after a binary STL's 84-byte header are all text (printable ASCII or
/// blanks). Triangle records are floats: a normal or a coordinate of 0, or any of many
/// others, has bytes that are not text.
bool textAfterStlHeader(std::string_view head) {
  for (std::size_t k = 84; k < head.size(); ++k)
    if (!isTextByte(head[k])) return false;
  return true;
}

/// Whether `head` holds a well-formed OBJ vertex ("v" and three or more numbers) or face ("f"
/// and three or more indices) on a whole line before its first byte that is not text. An OBJ
/// may open with any statement (an unknown one is kept and written back), so its first line
/// need not say OBJ; a binary STL's triangle records are floats, whose bytes can spell "\nv "
/// but not a whole such line in text before any other byte.
bool hasObjStatement(std::string_view head) {
  std::size_t text = 0;
  while (text < head.size() && isTextByte(head[text])) ++text;
  const std::size_t last_line_end = head.substr(0, text).rfind('\n');
  if (last_line_end == std::string_view::npos) return false;
  Lexer lex(head.substr(0, last_line_end + 1), 0);
  while (lex.nextLine()) {
    const std::string_view w = lex.token();
    if (w != "v" && w != "f") continue;
    std::size_t values = 0;
    bool ok = true;
    for (std::string_view t = lex.token(); ok && !t.empty(); t = lex.token(), ++values) {
      if (w == "v") {
        double d = 0;
        ok = parseFloating(t, &d);
      } else {  // an index, maybe negative, maybe with /vt/vn
        const std::size_t digit = t[0] == '-' ? 1 : 0;
        ok = t.size() > digit && t[digit] >= '0' && t[digit] <= '9';
      }
    }
    if (ok && values >= 3) return true;
  }
  return false;
}

/// The format of a file's first bytes (`size`: the whole file's); nullopt if none matches.
/// `binary_stl`: whether a size that fits a binary STL makes it one.
std::optional<FileFormat> sniff(std::string_view head, std::uint64_t size, bool binary_stl = true) {
  if (head.rfind("ply\n", 0) == 0 || head.rfind("ply\r\n", 0) == 0) return FileFormat::Ply;
  if (head.rfind("# .PCD", 0) == 0) return FileFormat::Pcd;
  if (head.rfind("LASF", 0) == 0) return FileFormat::Las;
  if (binary_stl && sizeOfBinaryStl(head, size)) return FileFormat::Stl;
  Lexer lex(head, 0);
  std::size_t header_columns = 0;         // XYZ: a first line of names, then rows of as many numbers
  bool first = true, count_line = false;  // PTS: a first line with the point count
  while (lex.nextLine()) {
    if (lex.peek() == '#') continue;
    const std::string_view text = lex.lineText();
    const std::string_view line = text.substr(0, xyzCommentStart(text));  // an XYZ row's "# note"
    const std::string_view w = lex.token();
    if (first) {
      first = false;
      const std::string up = lower(w);
      if (up == "version" || up == "fields") return FileFormat::Pcd;
      if (isOffKeyword(w)) return FileFormat::Off;
      if (up == "solid") return FileFormat::Stl;  // SOLID too
      if (w == "v" || w == "vn" || w == "vt" || w == "f" || w == "o" || w == "g" || w == "mtllib" ||
          w == "usemtl")
        return FileFormat::Obj;
      const std::size_t cols = numericColumns(line);
      if (cols >= 3) return FileFormat::Xyz;
      if (cols == 1 && plainUnsigned(w)) {
        count_line = true;
        continue;
      }
      if (cols == 0) {
        header_columns = splitColumns(line.substr(line.rfind("//", 0) == 0 ? 2 : 0)).size();
        if (header_columns >= 3) continue;
      }
      return std::nullopt;
    }
    // After a PTS count, a row of numbers; after an XYZ header, as many numbers as names.
    if (count_line) return numericColumns(line) >= 3 ? std::optional(FileFormat::Pts) : std::nullopt;
    if (numericColumns(line) == header_columns) return FileFormat::Xyz;
    return std::nullopt;
  }
  return std::nullopt;
}

}  // namespace

bool io_internal::binaryStlSizeFits(const unsigned char* count, std::uint64_t size) {
  std::uint32_t n = 0;
  std::memcpy(&n, count, 4);
  if (kHostBigEndian) n = __builtin_bswap32(n);
  return 84 + 50 * std::uint64_t{n} == size;
}

FileFormat formatFromPath(const std::string& path) {
  const std::string ext = lower(fs::path(path).extension().string());
  if (const auto f = formatOfExtension(ext)) return *f;
  fail(path, "unsupported file extension " + excerpt(ext) +
                 " (expected .ply, .pcd, .obj, .xyz, .txt, .pts, .las, .off or .stl)");
}

FileFormat sniffFormat(const std::string& path) {
  InputFile in(path);
  const std::uint64_t size = in.size();
  std::string head(static_cast<std::size_t>(std::min<std::uint64_t>(in.remaining(), 4096)), '\0');
  in.read(head.data(), head.size(), "the first bytes");
  if (const auto f = sniff(head, size)) return *f;
  fail(path, "the content matches no format hgdeform reads (PLY, PCD, OBJ, XYZ/TXT, PTS, LAS, OFF, STL)");
}

namespace {
/// A path with a NUL byte would be cut there by the system (another file): refused.
void refuseNul(const std::string& path) {
  const std::size_t nul = path.find('\0');
  if (nul != std::string::npos)
    fail(path.substr(0, nul) + "\\0" + path.substr(nul + 1), "the path holds a NUL byte");
}
}  // namespace

namespace {

/// readShape, or with `layout` readRecordLayout's reading (the points' records placed, not read).
Shape readShapeAs(const std::string& path, RecordLayout* layout) {
  refuseNul(path);
  const std::string ext = lower(fs::path(path).extension().string());
  const std::optional<FileFormat> by_ext = formatOfExtension(ext);
  std::optional<FileFormat> by_content;
  {
    InputFile in(path);  // missing, unreadable, a folder, empty: said here
    const std::uint64_t size = in.size();
    std::string head(static_cast<std::size_t>(std::min<std::uint64_t>(in.remaining(), 4096)), '\0');
    in.read(head.data(), head.size(), "the first bytes");
    by_content = sniff(head, size);
    // A binary STL is known by its size alone, which a text file can match by chance (bytes
    // 80-83 read as a triangle count; an OBJ's comment can hold any bytes). A file named for a
    // text format stays one when its text says so too (for an OBJ, a vertex or face statement
    // on any line: its first may be one the format does not know), or when what follows the
    // would-be header is text, which no triangle record is.
    if (by_content == FileFormat::Stl && by_ext && by_ext != FileFormat::Stl) {
      const std::optional<FileFormat> as_text = sniff(head, size, /*binary_stl=*/false);
      if (as_text == by_ext || (by_ext == FileFormat::Obj && hasObjStatement(head)))
        by_content = by_ext;
      else if (textAfterStlHeader(head))
        by_content = as_text ? as_text : by_ext;
    }
  }
  // A file named for its format is read as such when its content shows no other (a damaged
  // file gets that format's own, precise error); content of a known format wins over the name.
  if (!by_content && !by_ext)
    fail(path,
         "the content matches no format hgdeform reads (PLY, PCD, OBJ, XYZ/TXT, PTS, LAS, OFF, STL), and the "
         "extension " +
             excerpt(ext) + " names none");
  const FileFormat format = by_content ? *by_content : *by_ext;
  if (layout && format != FileFormat::Ply && format != FileFormat::Pcd)
    fail(path, std::string("cannot read the points in place (") + formatName(format) +
                   " files: only binary PLY and PCD); read the whole file instead");
  Shape shape;
  switch (format) {
    case FileFormat::Ply: shape = readPly(path, layout); break;
    case FileFormat::Pcd: shape = readPcd(path, layout); break;
    case FileFormat::Obj: shape = readObj(path); break;
    case FileFormat::Xyz:
    case FileFormat::Pts: shape = readXyz(path); break;
    case FileFormat::Las: shape = readLas(path); break;
    case FileFormat::Off: shape = readOff(path); break;
    case FileFormat::Stl: shape = readStl(path); break;
  }
  if (by_ext != format)
    shape.warnings.insert(shape.warnings.begin(), path + ": the content was read as " + formatName(format) +
                                                      " although the extension " +
                                                      (ext.empty() ? std::string("(none)") : excerpt(ext)) +
                                                      " says " + (by_ext ? formatName(*by_ext) : "nothing"));
  shape.path = path;
  shape.format = format;
  return shape;
}

}  // namespace

Shape readShape(const std::string& path) {
  return readShapeAs(path, nullptr);
}

RecordLayout readRecordLayout(const std::string& path) {
  RecordLayout layout;
  layout.shape = readShapeAs(path, &layout);
  return layout;
}

std::string extrasLost(const Shape& shape, FileFormat format) {
  const FileExtras& x = shape.extras;
  std::vector<std::string> lost;
  if (!x.obj_lines.empty() && format != FileFormat::Obj)
    lost.emplace_back(std::string("the OBJ's texture coordinates, ") +
                      (findXyzFields(shape.cloud).hasNormals() ? "" : "normals, ") +
                      "groups, materials, face corners, vertex weights and colours of some vertices only are "
                      "kept only when writing OBJ");
  if (!x.ply_elements.empty() && format != FileFormat::Ply)
    lost.emplace_back(
        "the PLY's other elements, face properties and list properties are kept only when writing PLY");
  if (!x.las_header.empty() && format != FileFormat::Las)
    lost.emplace_back(
        "the LAS's header, VLRs (its coordinate system among them) and EVLRs are kept only when "
        "writing LAS");
  if (format == FileFormat::Las)
    if (std::string las = lasLosses(shape); !las.empty()) lost.push_back(std::move(las));
  if (shape.isMesh() && (format == FileFormat::Pcd || format == FileFormat::Xyz ||
                         format == FileFormat::Pts || format == FileFormat::Las))
    lost.push_back(std::string(formatName(format)) + " holds points only: the " + num(shape.polygons.size()) +
                   " faces are dropped");
  if (format == FileFormat::Stl || format == FileFormat::Off || format == FileFormat::Obj ||
      format == FileFormat::Pts) {
    // STL holds positions and triangles only; OFF and OBJ also normals and colours. The fields
    // as the writer gets them: a packed colour is written as red, green and blue.
    pcl::PCLPointCloud2 converted;
    const pcl::PCLPointCloud2& c = conventionalCloud(shape, format, &converted) ? converted : shape.cloud;
    const XyzFields xyz = findXyzFields(c);
    const bool rgb = findField(c, "red") >= 0 && findField(c, "green") >= 0 && findField(c, "blue") >= 0;
    std::string fields;
    for (std::size_t k = 0; k < c.fields.size(); ++k) {
      const std::string& name = c.fields[k].name;
      const int i = static_cast<int>(k);
      const bool colour = rgb && (name == "red" || name == "green" || name == "blue");
      const bool kept =
          i == xyz.x || i == xyz.y || i == xyz.z || name == "_" ||
          (format == FileFormat::Off && ((xyz.hasNormals() && (i == xyz.nx || i == xyz.ny || i == xyz.nz)) ||
                                         colour || (rgb && name == "alpha"))) ||
          (format == FileFormat::Obj &&
           ((xyz.hasNormals() && (i == xyz.nx || i == xyz.ny || i == xyz.nz)) || colour)) ||
          (format == FileFormat::Pts && (colour || ptsIntensity(c, xyz) == i));
      if (!kept) fields += (fields.empty() ? "" : ", ") + name;
    }
    if (!fields.empty())
      lost.push_back(std::string(formatName(format)) + " cannot hold the fields " + fields);
  }
  if (format == FileFormat::Stl)
    if (std::string stl = stlLosses(shape); !stl.empty()) lost.push_back(std::move(stl));
  if ((format == FileFormat::Ply || format == FileFormat::Off) && shape.format != format) {
    const pcl::PCLPointCloud2& c = shape.cloud;
    const int r = findField(c, "red"), g = findField(c, "green"), b = findField(c, "blue");
    if (r >= 0 && g >= 0 && b >= 0 && unitColours(c, {r, g, b}))
      lost.emplace_back(std::string(formatName(format)) +
                        " gets the 0..1 colours as 0..255 red green blue, as its readers take them");
  }
  if (format == FileFormat::Pcd) {
    pcl::PCLPointCloud2 converted;
    if (conventionalCloud(shape, format, &converted)) {
      const XyzFields before = findXyzFields(shape.cloud), after = findXyzFields(converted);
      if (before.hasNormals() && after.hasNormals() &&
          shape.cloud.fields[static_cast<std::size_t>(before.nx)].datatype == Field::FLOAT64 &&
          converted.fields[static_cast<std::size_t>(after.nx)].datatype == Field::FLOAT32)
        lost.emplace_back(
            "PCD gets the double normals as float normal_x normal_y normal_z (the type PCL's "
            "and Open3D's readers take)");
    }
  }
  std::string out;
  for (const std::string& l : lost) out += (out.empty() ? "" : "; ") + l;
  return out;
}

void writeShape(const std::string& path, const Shape& shape, const WriteOptions& options) {
  refuseNul(path);
  const FileFormat format = formatFromPath(path);
  refuseInputs(path, {shape.path});
  const bool ascii = options.encoding == Encoding::Ascii;
  // Read from another format: the fields under the names the target format's readers know.
  pcl::PCLPointCloud2 converted;
  const bool convert = conventionalCloud(shape, format, &converted);
  // The shape with the converted cloud, all else as it was (reading's warnings are not written).
  const Shape renamed =
      convert ? Shape{std::move(converted), shape.polygons, shape.sensor_origin, shape.sensor_orientation,
                      shape.path,           shape.format,   shape.extras,        {}}
              : Shape{};
  const Shape& s = convert ? renamed : shape;
  switch (format) {
    case FileFormat::Ply: writePly(path, s, ascii); break;
    case FileFormat::Pcd: writePcd(path, s, ascii); break;
    case FileFormat::Obj: writeObj(path, s); break;
    case FileFormat::Xyz: writeXyz(path, s, false); break;
    case FileFormat::Pts: writeXyz(path, s, true); break;
    case FileFormat::Las: writeLas(path, s); break;
    case FileFormat::Off: writeOff(path, s); break;
    case FileFormat::Stl: writeStl(path, s, ascii); break;
  }
}

void writeRecords(const std::string& path, const RecordLayout& layout,
                  const std::function<void(RecordSink&)>& records) {
  refuseNul(path);
  const FileFormat format = formatFromPath(path);
  refuseInputs(path, {layout.shape.path});
  const Shape& shape = layout.shape;
  if (!shape.polygons.empty())
    fail(path, "cannot write the records as they come: a mesh's faces are not streamed");
  if (format != shape.format || (format != FileFormat::Ply && format != FileFormat::Pcd) ||
      shape.extras.pcd_compressed || shape.extras.ply_big_endian)
    fail(path, std::string("cannot write the records as they come: the output must be a binary ") +
                   formatName(shape.format) + " as the input is");
  struct Sink : RecordSink {
    AtomicWriter* w = nullptr;
    std::uint64_t bytes = 0;
    void write(const std::uint8_t* p, std::size_t n) override {
      w->write(p, n);
      bytes += n;
    }
    std::string file() const override { return w->temporary(); }
    std::uint64_t offset() const override { return w->written(); }
    void skip(std::uint64_t n) override {
      w->skip(n);
      bytes += n;
    }
  };
  const std::function<void(AtomicWriter&)> hook = [&](AtomicWriter& w) {
    Sink sink;
    sink.w = &w;
    records(sink);
    if (sink.bytes != layout.count * layout.bytes)
      fail(path, "cannot write: " + num(sink.bytes) + " bytes of records given for " + num(layout.count) +
                     " records of " + num(layout.bytes) + " bytes");
  };
  struct Restore {
    ~Restore() { t_streamed_records = nullptr; }
  } restore;
  t_streamed_records = &hook;
  if (format == FileFormat::Ply)
    writePly(path, shape, false);
  else
    writePcd(path, shape, false);
}

}  // namespace hgd
