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

// A channel written beside R, G, B, always as 32-bit float (sample counts up to 65536 are exact
// there, not in half): one value per pixel, row-major. Named as compositing tools expect a layer,
// e.g. "error.Y" (layer "error", luminance-like single channel).
struct ExrChannel {
  std::string name;
  const std::vector<float>* values;
};

// Writes R, G, B channels (ZIP compressed, lossless), and `extra` channels. kHalf converts R, G, B
// to 16-bit half floats; values beyond half's range (65504) are clamped to it and NaN is written
// as 0, so no Inf or NaN is ever produced by the conversion itself. Throws ExrError naming the
// path on failure (also for an extra channel of the wrong size or a name that is taken).
void write_exr(const std::string& path, const ImageRGB& image, const ExrAttributes& attributes = {},
               ExrPixelType type = ExrPixelType::kFloat, const std::vector<ExrChannel>& extra = {});

// How many threads compress and decompress EXR line blocks (OpenEXR's global pool, so for the
// whole process): 0, the default, means one per hardware thread. The bytes written do not depend
// on it. Why: ZIP compression of a float frame is single-threaded otherwise and took as long as
// rendering the frame (1920x1080 with error layers: 0.80 s to write, 0.89 s to render on two
// cores; docs/performance.md). `tessera render --threads N` sets it to N.
void set_exr_threads(int threads);

// Reads an EXR with R, G, B channels (missing channels read as 0) into float.
ImageRGB read_exr(const std::string& path, ExrAttributes* attributes = nullptr);

// Reads one channel of an EXR as float, row-major; throws ExrError if the file has no such channel.
std::vector<float> read_exr_channel(const std::string& path, const std::string& name);

}  // namespace tessera
