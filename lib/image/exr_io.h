// SPDX-License-Identifier: Apache-2.0
// OpenEXR reading and writing of float RGB images with string/number metadata.
#pragma once

#include <map>
#include <stdexcept>
#include <string>
#include <variant>
#include <vector>

#include "image/image.h"

namespace tessera {

// Header attributes written next to the pixels (renderer, spp, render time, rays...).
using ExrAttribute = std::variant<std::string, double, int64_t>;
using ExrAttributes = std::map<std::string, ExrAttribute>;

enum class ExrPixelType { kFloat, kHalf };

// How the pixels are compressed in the file. Lossless ones only: whichever is chosen, a float
// frame reads back bit for bit. (PXR24 rounds floats to 24 bits and B44 and DWA quantize: they
// would break the promise that the EXR holds the renderer's pixels exactly.) Measured on three
// rendered frames (bench/colors/exr_compression_bench; docs/colors.md, "EXR compression"): zip,
// the default here as in most renderers, halves a noisy float frame for about 0.25 us of CPU a
// pixel; piz is always the smallest (5-8 % below zip) at 0.74-1.3x zip's time; none writes in a
// tenth of zip's time at twice the size.
enum class ExrCompression { kNone, kRle, kZips, kZip, kPiz };

// The names the command line takes: none, rle, zips, zip, piz.
const std::vector<std::string>& exr_compression_names();
std::string exr_compression_name(ExrCompression c);
// Throws ExrError naming the allowed values for an unknown name.
ExrCompression parse_exr_compression(const std::string& name);

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

// Writes R, G, B channels (compressed losslessly, ZIP by default), and `extra` channels. kHalf converts R, G, B
// to 16-bit half floats; values beyond half's range (65504) are clamped to it and NaN is written
// as 0, so no Inf or NaN is ever produced by the conversion itself. Throws ExrError naming the
// path on failure (also for an extra channel of the wrong size or a name that is taken).
void write_exr(const std::string& path, const ImageRGB& image, const ExrAttributes& attributes = {},
               ExrPixelType type = ExrPixelType::kFloat, const std::vector<ExrChannel>& extra = {},
               ExrCompression compression = ExrCompression::kZip);

// How many threads compress and decompress EXR line blocks (OpenEXR's global pool, so for the
// whole process): 0, the default, means one per hardware thread. The bytes written do not depend
// on it. Why: ZIP compression of a float frame is single-threaded otherwise and took as long as
// rendering the frame (1920x1080 with error layers: 0.80 s to write, 0.89 s to render on two
// cores; docs/performance.md, "EXR writing"). `tessera render --threads N` sets it to N.
void set_exr_threads(int threads);

// Reads an EXR with R, G, B channels (missing channels read as 0) into float.
ImageRGB read_exr(const std::string& path, ExrAttributes* attributes = nullptr);

// Reads one channel of an EXR as float, row-major; throws ExrError if the file has no such channel.
std::vector<float> read_exr_channel(const std::string& path, const std::string& name);

}  // namespace tessera
