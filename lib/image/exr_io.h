// OpenEXR reading and writing of float RGB images with string/number metadata.
#pragma once

#include <map>
#include <stdexcept>
#include <string>
#include <variant>

#include "image/image.h"

namespace tessera {

// Header attributes written next to the pixels (renderer, spp, render time, rays...).
using ExrAttribute = std::variant<std::string, double, int64_t>;
using ExrAttributes = std::map<std::string, ExrAttribute>;

enum class ExrPixelType { kFloat, kHalf };

class ExrError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

// Writes R, G, B channels (ZIP compressed, lossless). kHalf converts to 16-bit half floats;
// values beyond half's range (65504) are clamped to it and NaN is written as 0, so no Inf or
// NaN is ever produced by the conversion itself. Throws ExrError naming the path on failure.
void write_exr(const std::string& path, const ImageRGB& image, const ExrAttributes& attributes = {},
               ExrPixelType type = ExrPixelType::kFloat);

// Reads an EXR with R, G, B channels (missing channels read as 0) into float.
ImageRGB read_exr(const std::string& path, ExrAttributes* attributes = nullptr);

}  // namespace tessera
