// The public entry points: a shape's format from its path, and reading and writing a shape in
// any of the formats.
#include <filesystem>

#include "internal.h"

namespace hgd {

using namespace io_internal;
namespace fs = std::filesystem;

FileFormat formatFromPath(const std::string& path) {
  const std::string ext = lower(fs::path(path).extension().string());
  if (ext == ".ply") return FileFormat::Ply;
  if (ext == ".pcd") return FileFormat::Pcd;
  if (ext == ".obj") return FileFormat::Obj;
  fail(path, "unsupported file extension " + excerpt(ext) + " (expected .ply, .pcd or .obj)");
}

Shape readShape(const std::string& path) {
  const FileFormat format = formatFromPath(path);
  Shape shape;
  switch (format) {
    case FileFormat::Ply: shape = readPly(path); break;
    case FileFormat::Pcd: shape = readPcd(path); break;
    case FileFormat::Obj: shape = readObj(path); break;
  }
  shape.path = path;
  shape.format = format;
  return shape;
}

std::string extrasLost(const Shape& shape, FileFormat format) {
  const FileExtras& x = shape.extras;
  if (!x.obj_lines.empty() && format != FileFormat::Obj)
    return "the OBJ's texture coordinates, normals, groups, materials and face corners are kept only when "
           "writing OBJ";
  if (!x.ply_elements.empty() && format != FileFormat::Ply)
    return "the PLY's other elements, face properties and list properties are kept only when writing PLY";
  return "";
}

void writeShape(const std::string& path, const Shape& shape, const WriteOptions& options) {
  const FileFormat format = formatFromPath(path);
  refuseInputs(path, {shape.path});
  const bool ascii = options.encoding == Encoding::Ascii;
  switch (format) {
    case FileFormat::Ply: writePly(path, shape, ascii); break;
    case FileFormat::Pcd: writePcd(path, shape, ascii); break;
    case FileFormat::Obj: writeObj(path, shape); break;
  }
}

}  // namespace hgd
