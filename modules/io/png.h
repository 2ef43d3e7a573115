// 8-bit greyscale / RGB PNG writing (ITK PNG IO), for QC figures and previews.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

namespace ms::io {

// pixels: row-major, width*height (channels = 1) or width*height*3 (channels = 3),
// row 0 at the top of the picture.
void write_png(const std::string& path, const std::vector<std::uint8_t>& pixels, int width, int height, int channels);

}  // namespace ms::io
