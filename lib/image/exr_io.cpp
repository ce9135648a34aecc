// SPDX-License-Identifier: Apache-2.0
#include "image/exr_io.h"

#include <ImfChannelList.h>
#include <ImfDoubleAttribute.h>
#include <ImfFrameBuffer.h>
#include <ImfHeader.h>
#include <ImfInputFile.h>
#include <ImfIntAttribute.h>
#include <ImfOutputFile.h>
#include <ImfStringAttribute.h>
#include <ImfThreading.h>
#include <Iex.h>
#include <half.h>
#include <spdlog/spdlog.h>

#include <algorithm>
#include <cmath>
#include <mutex>
#include <thread>
#include <vector>

namespace tessera {

namespace {

std::mutex exr_threads_mutex;
int exr_threads_wanted = 0;  // 0: one per hardware thread
bool exr_threads_set = false;

// OpenEXR's global thread count, set once before the first file this process reads or writes
// (or again after set_exr_threads changes it): the files then share the pool.
int exr_threads() {
  std::lock_guard lock(exr_threads_mutex);
  const int n = exr_threads_wanted > 0 ? exr_threads_wanted : int(std::max(1u, std::thread::hardware_concurrency()));
  if (!exr_threads_set) {
    Imf::setGlobalThreadCount(n);
    exr_threads_set = true;
  }
  return n;
}

half to_half_clamped(float v) {
  if (std::isnan(v)) return half(0.0f);
  constexpr float kHalfMax = 65504.0f;
  return half(std::clamp(v, -kHalfMax, kHalfMax));
}

}  // namespace

const std::vector<std::string>& exr_compression_names() {
  static const std::vector<std::string> names{"none", "rle", "zips", "zip", "piz"};
  return names;
}

std::string exr_compression_name(ExrCompression c) { return exr_compression_names().at(size_t(c)); }

ExrCompression parse_exr_compression(const std::string& name) {
  const auto& names = exr_compression_names();
  std::string allowed;
  for (size_t i = 0; i < names.size(); ++i) {
    if (names[i] == name) return ExrCompression(i);
    allowed += (i ? ", " : "") + names[i];
  }
  throw ExrError("unknown EXR compression \"" + name + "\"; allowed: " + allowed + " (lossless only)");
}

void set_exr_threads(int threads) {
  std::lock_guard lock(exr_threads_mutex);
  exr_threads_wanted = std::max(0, threads);
  exr_threads_set = false;
}

void write_exr(const std::string& path, const ImageRGB& image, const ExrAttributes& attributes,
               ExrPixelType type, const std::vector<ExrChannel>& extra, ExrCompression compression) {
  if (image.width <= 0 || image.height <= 0) {
    throw ExrError("cannot write " + path + ": empty image");
  }
  try {
    Imf::Header header(image.width, image.height);
    static constexpr Imf::Compression kImf[] = {Imf::NO_COMPRESSION, Imf::RLE_COMPRESSION, Imf::ZIPS_COMPRESSION,
                                                Imf::ZIP_COMPRESSION, Imf::PIZ_COMPRESSION};
    header.compression() = kImf[size_t(compression)];
    const Imf::PixelType pt = type == ExrPixelType::kFloat ? Imf::FLOAT : Imf::HALF;
    for (const char* c : {"R", "G", "B"}) header.channels().insert(c, Imf::Channel(pt));
    for (const ExrChannel& c : extra) {
      if (c.values->size() != image.pixel_count()) {
        throw ExrError("cannot write " + path + ": channel " + c.name + " has " + std::to_string(c.values->size()) +
                       " values for " + std::to_string(image.pixel_count()) + " pixels");
      }
      if (header.channels().findChannel(c.name)) throw ExrError("cannot write " + path + ": two channels named " + c.name);
      header.channels().insert(c.name, Imf::Channel(Imf::FLOAT));
    }
    for (const auto& [name, value] : attributes) {
      if (const auto* s = std::get_if<std::string>(&value)) {
        header.insert(name, Imf::StringAttribute(*s));
      } else if (const auto* d = std::get_if<double>(&value)) {
        header.insert(name, Imf::DoubleAttribute(*d));
      } else {
        header.insert(name, Imf::IntAttribute(int(std::get<int64_t>(value))));
      }
    }
    Imf::FrameBuffer fb;
    const size_t xs = 3 * sizeof(float), ys = xs * size_t(image.width);
    std::vector<half> halfs;
    if (type == ExrPixelType::kFloat) {
      char* base = reinterpret_cast<char*>(const_cast<float*>(image.rgb.data()));
      for (int c = 0; c < 3; ++c) {
        fb.insert(c == 0 ? "R" : c == 1 ? "G" : "B",
                  Imf::Slice(Imf::FLOAT, base + c * sizeof(float), xs, ys));
      }
    } else {
      halfs.resize(image.rgb.size());
      std::transform(image.rgb.begin(), image.rgb.end(), halfs.begin(), to_half_clamped);
      // Clamping changes the picture: say so (once per file), never silently.
      size_t clamped = 0, nans = 0;
      for (float v : image.rgb) {
        nans += std::isnan(v);
        clamped += std::abs(v) > 65504.0f;
      }
      if (clamped || nans) {
        spdlog::warn("{}: {} values beyond half-float range clamped to +-65504, {} NaN written as 0", path, clamped,
                     nans);
      }
      char* base = reinterpret_cast<char*>(halfs.data());
      const size_t hxs = 3 * sizeof(half), hys = hxs * size_t(image.width);
      for (int c = 0; c < 3; ++c) {
        fb.insert(c == 0 ? "R" : c == 1 ? "G" : "B",
                  Imf::Slice(Imf::HALF, base + c * sizeof(half), hxs, hys));
      }
    }
    for (const ExrChannel& c : extra) {
      fb.insert(c.name, Imf::Slice(Imf::FLOAT, reinterpret_cast<char*>(const_cast<float*>(c.values->data())),
                                   sizeof(float), sizeof(float) * size_t(image.width)));
    }
    Imf::OutputFile file(path.c_str(), header, exr_threads());
    file.setFrameBuffer(fb);
    file.writePixels(image.height);
  } catch (const ExrError&) {
    throw;
  } catch (const std::exception& e) {
    throw ExrError("cannot write EXR " + path + ": " + e.what());
  }
}

ImageRGB read_exr(const std::string& path, ExrAttributes* attributes) {
  try {
    Imf::InputFile file(path.c_str(), exr_threads());
    const Imath::Box2i dw = file.header().dataWindow();
    const int w = dw.max.x - dw.min.x + 1, h = dw.max.y - dw.min.y + 1;
    ImageRGB image(w, h);
    Imf::FrameBuffer fb;
    const size_t xs = 3 * sizeof(float), ys = xs * size_t(w);
    // OpenEXR addresses slices by absolute data-window coordinates: shift the base pointer.
    char* base = reinterpret_cast<char*>(image.rgb.data()) -
                 ptrdiff_t(dw.min.x) * ptrdiff_t(xs) - ptrdiff_t(dw.min.y) * ptrdiff_t(ys);
    for (int c = 0; c < 3; ++c) {
      fb.insert(c == 0 ? "R" : c == 1 ? "G" : "B",
                Imf::Slice(Imf::FLOAT, base + c * sizeof(float), xs, ys, 1, 1, 0.0));
    }
    file.setFrameBuffer(fb);
    file.readPixels(dw.min.y, dw.max.y);
    if (attributes) {
      for (auto it = file.header().begin(); it != file.header().end(); ++it) {
        const Imf::Attribute& a = it.attribute();
        if (const auto* s = dynamic_cast<const Imf::StringAttribute*>(&a)) {
          (*attributes)[it.name()] = s->value();
        } else if (const auto* d = dynamic_cast<const Imf::DoubleAttribute*>(&a)) {
          (*attributes)[it.name()] = d->value();
        } else if (const auto* i = dynamic_cast<const Imf::IntAttribute*>(&a)) {
          (*attributes)[it.name()] = int64_t(i->value());
        }
      }
    }
    return image;
  } catch (const std::exception& e) {
    throw ExrError("cannot read EXR " + path + ": " + e.what());
  }
}

std::vector<float> read_exr_channel(const std::string& path, const std::string& name) {
  try {
    Imf::InputFile file(path.c_str(), exr_threads());
    if (!file.header().channels().findChannel(name)) throw ExrError(path + " has no channel " + name);
    const Imath::Box2i dw = file.header().dataWindow();
    const int w = dw.max.x - dw.min.x + 1, h = dw.max.y - dw.min.y + 1;
    std::vector<float> values(size_t(w) * size_t(h));
    const size_t xs = sizeof(float), ys = xs * size_t(w);
    char* base = reinterpret_cast<char*>(values.data()) - ptrdiff_t(dw.min.x) * ptrdiff_t(xs) -
                 ptrdiff_t(dw.min.y) * ptrdiff_t(ys);
    Imf::FrameBuffer fb;
    fb.insert(name, Imf::Slice(Imf::FLOAT, base, xs, ys));
    file.setFrameBuffer(fb);
    file.readPixels(dw.min.y, dw.max.y);
    return values;
  } catch (const ExrError&) {
    throw;
  } catch (const std::exception& e) {
    throw ExrError("cannot read EXR " + path + ": " + e.what());
  }
}

}  // namespace tessera
