// PCD reading and writing: ascii, binary and binary_compressed (LZF), organized clouds, the
// VIEWPOINT, padding fields.
#include <lzf.h>  // Debian liblzf

#include <algorithm>
#include <cmath>
#include <cstring>
#include <limits>
#include <string>
#include <vector>

#include "io/internal.h"

namespace hgd::io_internal {

Shape readPcd(const std::string& path, RecordLayout* layout) {
  InputFile in(path);
  std::vector<std::string> names;
  std::vector<std::uint64_t> sizes, counts;
  std::vector<char> types;
  bool have_fields = false, have_size = false, have_type = false, have_count = false, have_width = false,
       have_height = false, have_points = false, have_viewpoint = false, have_version = false,
       have_data = false;
  std::uint64_t width = 0, height = 0, points = 0;
  double viewpoint[7] = {0, 0, 0, 1, 0, 0, 0};
  std::string data_kind, line;

  while (in.readLine(&line, kMaxHeaderLine)) {
    const auto bad = [&](const std::string& why) {
      fail(path, "malformed header: line " + num(in.linesRead()) + ": " + why + " (" + excerpt(line) + ")");
    };
    const auto words = splitWords(line);
    if (words.empty() || words[0][0] == '#') continue;
    std::string kw = lower(words[0]);
    const auto once = [&](bool* seen) {
      if (*seen) bad("repeated " + kw);
      *seen = true;
    };
    const auto numbers = [&](std::vector<std::uint64_t>* out) {
      if (words.size() < 2) bad("no values");
      for (std::size_t i = 1; i < words.size(); ++i) {
        std::uint64_t v = 0;
        if (!parseU64(words[i], &v)) bad("bad number " + excerpt(words[i]));
        out->push_back(v);
      }
    };
    const auto single = [&](std::uint64_t* out) {
      if (words.size() != 2 || !parseU64(words[1], out)) bad("expected one non-negative integer");
    };
    if (kw == "version") {
      once(&have_version);
      static const char* const known[] = {"0.7", ".7", "0.6", ".6", "0.5", ".5"};
      if (words.size() != 2) bad("expected 'VERSION <version>'");
      if (std::none_of(std::begin(known), std::end(known), [&](const char* v) { return words[1] == v; }))
        fail(path, "unsupported PCD version " + excerpt(words[1]));
    } else if (kw == "fields" || kw == "columns") {
      once(&have_fields);
      if (words.size() < 2) bad("no field names");
      for (std::size_t i = 1; i < words.size(); ++i) names.emplace_back(words[i]);
    } else if (kw == "size") {
      once(&have_size);
      numbers(&sizes);
    } else if (kw == "type") {
      once(&have_type);
      if (words.size() < 2) bad("no types");
      for (std::size_t i = 1; i < words.size(); ++i) {
        if (words[i].size() != 1) bad("bad type " + excerpt(words[i]));
        types.push_back(static_cast<char>(std::toupper(static_cast<unsigned char>(words[i][0]))));
      }
    } else if (kw == "count") {
      once(&have_count);
      numbers(&counts);
    } else if (kw == "width" || kw == "height" || kw == "points") {
      // One number each, once.
      const bool w = kw == "width", h = kw == "height";
      once(w ? &have_width : h ? &have_height : &have_points);
      single(w ? &width : h ? &height : &points);
    } else if (kw == "viewpoint") {
      once(&have_viewpoint);
      if (words.size() != 8) bad("expected 7 numbers");
      for (std::size_t i = 0; i < 7; ++i)
        if (!parseFloating(words[i + 1], &viewpoint[i])) bad("bad number " + excerpt(words[i + 1]));
    } else if (kw == "data") {
      if (words.size() != 2) bad("expected 'DATA ascii|binary|binary_compressed'");
      data_kind = lower(words[1]);
      have_data = true;
      break;
    } else {
      bad("unknown keyword");
    }
  }
  if (!have_data) fail(path, "malformed header: no DATA line");
  if (!have_fields) fail(path, "malformed header: no FIELDS line");
  if (!have_size) fail(path, "malformed header: no SIZE line");
  if (!have_type) fail(path, "malformed header: no TYPE line");
  if (!have_count) counts.assign(names.size(), 1);
  if (sizes.size() != names.size() || types.size() != names.size() || counts.size() != names.size())
    fail(path, "malformed header: FIELDS has " + num(names.size()) + " entries but SIZE has " +
                   num(sizes.size()) + ", TYPE " + num(types.size()) + " and COUNT " + num(counts.size()));
  if (have_width) {
    if (!have_height) height = 1;
    std::uint64_t wh = 0;
    if (!mulOk(width, height, &wh)) fail(path, "malformed header: WIDTH x HEIGHT overflows");
    if (have_points && points != wh)
      fail(path, "malformed header: POINTS " + num(points) + " differs from WIDTH x HEIGHT = " + num(wh));
    points = wh;
  } else if (have_points) {
    width = points;
    height = 1;
  } else {
    fail(path, "malformed header: no WIDTH or POINTS line");
  }
  if (data_kind != "ascii" && data_kind != "binary" && data_kind != "binary_compressed")
    fail(path, "unsupported PCD data encoding " + excerpt(data_kind));

  Shape shape;
  pcl::PCLPointCloud2& cloud = shape.cloud;
  std::uint64_t step = 0, pad_bytes = 0, ascii_values = 0, ascii_values_pad = 0;
  for (std::size_t i = 0; i < names.size(); ++i) {
    const char t = types[i];
    const std::uint64_t s = sizes[i];
    const std::uint8_t dt = pcdDatatype(t, s);
    if (dt == 0 && t != 'I' && t != 'U' && t != 'F')
      fail(path, "malformed header: field '" + names[i] + "' has type " + std::string(1, t) +
                     " (expected I, U or F)");
    if (dt == 0)
      fail(path, "unsupported field type " + std::string(1, t) + num(s) + " for field '" + names[i] + "'");
    if (counts[i] == 0 || counts[i] > std::numeric_limits<std::uint32_t>::max())
      fail(path, "malformed header: field '" + names[i] + "' has COUNT " + num(counts[i]));
    Field f;
    f.name = names[i];
    f.offset =
        static_cast<std::uint32_t>(std::min<std::uint64_t>(step, std::numeric_limits<std::uint32_t>::max()));
    f.datatype = dt;
    f.count = static_cast<std::uint32_t>(counts[i]);
    cloud.fields.push_back(f);
    step += s * counts[i];  // <= 8 * 2^32 per field: no overflow for any plausible number of fields
    ascii_values_pad += counts[i];
    if (f.name == "_")
      pad_bytes += s * counts[i];
    else
      ascii_values += counts[i];
    if (step > std::numeric_limits<std::uint32_t>::max())
      fail(path, "unsupported: points of more than 4294967295 bytes");
  }
  if (points == 0) fail(path, "no points: the header declares 0 points");
  if (!findXyzFields(cloud).hasXyz()) fail(path, "no x/y/z fields: FIELDS has no x, y and z");

  // Check the declared size against the data actually present, before allocating anything.
  const std::uint64_t avail = in.remaining();
  std::uint64_t need = 0;
  const bool need_ok = mulOk(points, step, &need);
  const std::string declared = "header declares " + num(points) + " points of " + num(step) + " bytes";
  if (data_kind == "binary") {
    if (!need_ok || need > avail)
      fail(path, "truncated data: " + declared + " (" + (need_ok ? num(need) : std::string("too many")) +
                     " bytes), the file holds " + num(avail) + " bytes of data");
  } else if (data_kind == "ascii") {
    std::uint64_t tokens = 0;
    if (!mulOk(points, std::max<std::uint64_t>(ascii_values, 1), &tokens) || tokens > avail / 2 + 1)
      fail(path, "truncated data: " + declared + " (" + num(ascii_values) +
                     " values each), the file holds only " + num(avail) + " bytes of text");
    // Padding fields have no text in ascii, yet take memory: a header with a huge padding COUNT
    // must not make a few lines of text allocate gigabytes. A value takes at least two bytes of
    // text and at most eight in memory; padding up to a few times the data is what PCL writes.
    if (!need_ok || need > 16 * avail + (std::uint64_t{1} << 20))
      fail(path, "malformed header: " + declared + " (" + (need_ok ? num(need) : std::string("too many")) +
                     " bytes in memory), implausible for " + num(avail) + " bytes of ascii data");
  }
  std::uint32_t comp = 0, uncomp = 0;
  if (data_kind == "binary_compressed") {
    std::uint32_t block_sizes[2] = {0, 0};
    in.read(block_sizes, sizeof block_sizes, "compressed block sizes");
    comp = block_sizes[0];
    uncomp = block_sizes[1];
    in.require(comp, "compressed block");
    // LZF expands at most ~88x (a 3-byte back reference yields 264 bytes).
    std::uint64_t bound = 0;
    if (!need_ok || !mulOk(comp, 100, &bound) || need > bound + 1024)
      fail(path, "truncated data: " + declared + " (" + (need_ok ? num(need) : std::string("too many")) +
                     " bytes), the compressed block holds only " + num(comp) + " bytes");
  }
  if (width > std::numeric_limits<std::uint32_t>::max() || height > std::numeric_limits<std::uint32_t>::max())
    fail(path, "unsupported: WIDTH or HEIGHT above 4294967295");

  cloud.width = static_cast<std::uint32_t>(width);
  cloud.height = static_cast<std::uint32_t>(height);
  cloud.point_step = static_cast<std::uint32_t>(step);
  cloud.row_step = cloud.point_step * cloud.width;
  cloud.is_bigendian = false;
  shape.sensor_origin = Eigen::Vector4f(static_cast<float>(viewpoint[0]), static_cast<float>(viewpoint[1]),
                                        static_cast<float>(viewpoint[2]), 0.f);
  shape.sensor_orientation =
      Eigen::Quaternionf(static_cast<float>(viewpoint[3]), static_cast<float>(viewpoint[4]),
                         static_cast<float>(viewpoint[5]), static_cast<float>(viewpoint[6]));

  if (layout && data_kind != "binary")
    fail(path, "cannot read the points in place (" + data_kind + " PCD); read the whole file instead");
  if (data_kind == "binary" && layout) {
    layout->offset = in.offset();
    layout->count = points;
    layout->bytes = cloud.point_step;
    in.skip(need, "point data");
  } else if (data_kind == "binary") {
    cloud.data.resize(need);
    in.read(cloud.data.data(), need, "point data");
  }
  if (data_kind == "binary") {
    // PCL's binary writer sizes the file to whole pages: zeros after the last point are that
    // padding (PCL and Open3D read past them). Anything else there is data the header does not
    // declare.
    const std::uint64_t after = in.remaining();
    std::uint64_t nonzero = 0;
    for (std::uint64_t done = 0; done < after && nonzero == 0;) {
      std::uint8_t block[4096];
      const std::size_t len = static_cast<std::size_t>(std::min<std::uint64_t>(sizeof block, after - done));
      in.read(block, len, "data after the last point");
      for (std::size_t k = 0; k < len && nonzero == 0; ++k)
        if (block[k] != 0) nonzero = done + k + 1;
      done += len;
    }
    if (nonzero != 0)
      fail(path, "malformed data: " + num(after) + " bytes after the last point, not all zero (byte " +
                     num(nonzero) + " is not): more data than " + declared);
  } else if (data_kind == "binary_compressed") {
    shape.extras.pcd_compressed = true;
    const std::uint64_t need_nopad = points * (step - pad_bytes);
    if (uncomp != need && uncomp != need_nopad)
      fail(path, "malformed data: the compressed block declares " + num(uncomp) +
                     " bytes, the header implies " + num(need));
    std::vector<std::uint8_t> packed(comp);
    in.read(packed.data(), comp, "compressed block");
    std::vector<std::uint8_t> soa(uncomp);
    if (uncomp > 0) {
      const unsigned got = lzf_decompress(packed.data(), comp, soa.data(), uncomp);
      if (got != uncomp)
        fail(path, "malformed data: corrupt compressed block (LZF produced " + num(got) +
                       " bytes, expected " + num(uncomp) + ")");
    }
    cloud.data.assign(need, 0);
    const bool has_pad_data = uncomp == need;
    std::size_t toff = 0;
    for (const auto& f : cloud.fields) {
      const std::size_t fb = datatypeSize(f.datatype) * fieldCount(f);
      if (f.name == "_" && !has_pad_data) continue;
      for (std::size_t i = 0; i < points; ++i)
        std::memcpy(cloud.data.data() + i * step + f.offset, soa.data() + toff + i * fb, fb);
      toff += fb * points;
    }
  } else {
    cloud.data.assign(need, 0);
    Lexer lex(in.rest(), in.linesRead());
    const bool has_pad = ascii_values_pad != ascii_values;
    DecimalsSeen decimals;  // per field, for writing the values back as spelt
    for (std::uint64_t i = 0; i < points; ++i) {
      if (!lex.nextLine()) fail(path, "truncated data: expected " + num(points) + " points, found " + num(i));
      // PCL's writers omit padding values in ascii, some of its readers expect them: accept both.
      const bool pad_tokens = has_pad && lex.countTokens() == ascii_values_pad;
      std::uint8_t* pt = cloud.data.data() + i * step;
      for (std::size_t fi = 0; fi < cloud.fields.size(); ++fi) {
        const auto& f = cloud.fields[fi];
        const bool pad = f.name == "_";
        if (pad && !pad_tokens) continue;
        const std::size_t sz = datatypeSize(f.datatype);
        for (std::size_t k = 0; k < fieldCount(f); ++k) {
          const std::string_view tok = lex.token();
          if (tok.empty())
            fail(path, "truncated data: line " + num(lex.line()) + " (point " + num(i) + ") has fewer than " +
                           num(ascii_values) + " values");
          if (pad) continue;
          // A packed colour as PCL writes it (an integer: the bits); a float token as older
          // writers (hgdeform's too) wrote it.
          const std::uint8_t type =
              packedColour(f) && plainUnsigned(tok) ? std::uint8_t{Field::UINT32} : f.datatype;
          const Parse st = parseValue(tok, type, pt + f.offset + k * sz);
          decimals.see(fi, tok);
          if (st == Parse::Bad)
            fail(path, "non-numeric value " + excerpt(tok) + " at line " + num(lex.line()) + " (point " +
                           num(i) + ", field '" + f.name + "')");
          if (st == Parse::Range)
            fail(path, "value out of range " + excerpt(tok) + " at line " + num(lex.line()) + " (point " +
                           num(i) + ", field '" + f.name + "')");
        }
      }
      if (!lex.atLineEnd())
        fail(path, "malformed data: line " + num(lex.line()) + " (point " + num(i) + ") has more than " +
                       num(ascii_values) + " values");
    }
    if (lex.nextLine())
      fail(path, "malformed data: line " + num(lex.line()) + ": more data than the header declares (" +
                     num(points) + " points)");
    std::vector<std::string> field_names;
    for (const auto& f : cloud.fields) field_names.push_back(f.name);
    decimals.store(shape.extras, field_names);
  }
  cloud.is_dense = layout ? false : computeDense(cloud);
  return shape;
}

void writePcd(const std::string& path, const Shape& shape, bool ascii) {
  // Padding fields are kept in binary (the bytes are written as they are) and dropped in ascii,
  // where PCL's own writers and readers disagree about them.
  const auto fields = checkShape(path, shape, !ascii);
  const pcl::PCLPointCloud2& c = shape.cloud;
  const std::size_t n = shape.size();
  std::string h = "# .PCD v0.7 - Point Cloud Data file format\nVERSION 0.7\nFIELDS";
  for (const Field* f : fields) h += " " + f->name;
  h += "\nSIZE";
  for (const Field* f : fields) h += " " + num(datatypeSize(f->datatype));
  h += "\nTYPE";
  for (const Field* f : fields) {
    h += ' ';
    // Ascii: a packed colour is written as the integer of its bits (see writeAsciiPoints), so
    // its type is U, as PCL writes it (PCL reads an F value as a number, not as bits).
    h += ascii && packedColour(*f) ? 'U' : pcdTypeLetter(f->datatype);
  }
  h += "\nCOUNT";
  for (const Field* f : fields) h += " " + num(fieldCount(*f));
  h += "\nWIDTH " + num(c.width) + "\nHEIGHT " + num(c.height) + "\nVIEWPOINT";
  const float vp[7] = {shape.sensor_origin[0],       shape.sensor_origin[1],
                       shape.sensor_origin[2],       shape.sensor_orientation.w(),
                       shape.sensor_orientation.x(), shape.sensor_orientation.y(),
                       shape.sensor_orientation.z()};
  for (const float v : vp) {
    h += ' ';
    appendFloat(h, v);
  }
  // Compressed as it was read (binary_compressed: each field's values together, then LZF).
  const bool compressed = !ascii && shape.extras.pcd_compressed;
  h += "\nPOINTS " + num(n) + "\nDATA " +
       (ascii        ? "ascii"
        : compressed ? "binary_compressed"
                     : "binary") +
       "\n";

  AtomicWriter w(path);
  w.write(h);
  if (ascii) {
    writeAsciiPoints(w, c, n, fields, /*colour_bits=*/true, decimalsOf(shape.extras, fields));
  } else if (compressed) {
    std::vector<std::uint8_t> soa;
    for (const Field* f : fields) {
      const std::size_t fb = datatypeSize(f->datatype) * fieldCount(*f);
      for (std::size_t i = 0; i < n; ++i) {
        const std::uint8_t* src = c.data.data() + i * c.point_step + f->offset;
        soa.insert(soa.end(), src, src + fb);
      }
    }
    if (soa.size() > std::numeric_limits<std::uint32_t>::max() / 2)
      fail(path, "cannot write: too much data for one compressed PCD block");
    std::vector<std::uint8_t> packed(soa.size() + soa.size() / 2 + 64);
    const unsigned got = soa.empty() ? 0
                                     : lzf_compress(soa.data(), static_cast<unsigned>(soa.size()),
                                                    packed.data(), static_cast<unsigned>(packed.size()));
    if (!soa.empty() && got == 0) fail(path, "cannot write: LZF compression failed");
    const std::uint32_t sizes[2] = {got, static_cast<std::uint32_t>(soa.size())};
    w.write(sizes, sizeof sizes);
    w.write(packed.data(), got);
  } else {
    writePackedBinary(w, c, n, fields);
  }
  w.commit();
}

}  // namespace hgd::io_internal
