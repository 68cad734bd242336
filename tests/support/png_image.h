// A PNG read back as RGB bytes, for the tests that look at what the viewer and the renderer
// drew (header-only: the test programs that include it link libpng).
#pragma once

#include <png.h>

#include <cstddef>
#include <cstring>
#include <string>
#include <vector>

namespace hgdtest {

struct Image {
  int width = 0, height = 0;
  std::vector<unsigned char> rgb;
  const unsigned char* at(int x, int y) const {
    return rgb.data() +
           3 * (static_cast<std::size_t>(y) * static_cast<std::size_t>(width) + static_cast<std::size_t>(x));
  }
};

/// The picture at `path`, or an empty Image when it cannot be read.
inline Image readPng(const std::string& path) {
  Image img;
  png_image png;
  std::memset(&png, 0, sizeof png);
  png.version = PNG_IMAGE_VERSION;
  if (!png_image_begin_read_from_file(&png, path.c_str())) return img;
  png.format = PNG_FORMAT_RGB;
  img.width = static_cast<int>(png.width);
  img.height = static_cast<int>(png.height);
  img.rgb.resize(PNG_IMAGE_SIZE(png));
  if (!png_image_finish_read(&png, nullptr, img.rgb.data(), 0, nullptr)) img.rgb.clear();
  return img;
}

}  // namespace hgdtest
