// SPDX-License-Identifier: Apache-2.0
#include "color/rgbe.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <iterator>
#include <string_view>

#include "color/color_error.h"
#include "color/shared_exponent_clamp.h"

namespace tessera::color {

namespace {

// Radiance's scanline run-length encoding for one component: runs of >= 4 equal bytes as
// (128 + count, value), everything else as literal dumps (count, bytes...), count <= 127/128.
void encode_component_rle(const uint8_t* data, int n, std::vector<uint8_t>& out) {
  constexpr int kMinRun = 4;
  int cur = 0;
  while (cur < n) {
    // Find the start of the next run of at least kMinRun.
    int run_start = cur, run_len = 0;
    while (run_start < n) {
      run_len = 1;
      while (run_start + run_len < n && run_len < 127 &&
             data[run_start + run_len] == data[run_start]) {
        ++run_len;
      }
      if (run_len >= kMinRun) break;
      run_start += run_len;
      run_len = 0;
    }
    if (run_start > n) run_start = n;
    // Literal bytes before it.
    while (cur < run_start) {
      const int count = std::min(run_start - cur, 128);
      out.push_back(uint8_t(count));
      out.insert(out.end(), data + cur, data + cur + count);
      cur += count;
    }
    if (run_len >= kMinRun) {
      out.push_back(uint8_t(128 + run_len));
      out.push_back(data[run_start]);
      cur = run_start + run_len;
    }
  }
}

}  // namespace

Rgbe encode_rgbe(const Rgb& c) {
  const double r = clamp_shared_exponent_channel(c.r, kRgbeMax), g = clamp_shared_exponent_channel(c.g, kRgbeMax),
               b = clamp_shared_exponent_channel(c.b, kRgbeMax);
  const double v = std::max({r, g, b});
  if (v == 0.0) return {0, 0, 0, 0};
  int e = 0;
  std::frexp(v, &e);  // v = m * 2^e, m in [0.5, 1): v * 2^(8-e) in [128, 256)
  if (e + 128 < 1) return {0, 0, 0, 0};  // below 2^-128: no exponent byte for it
  // Round to nearest, capping at 255 rather than carrying into the next exponent: a
  // mantissa in [255.5, 256) then errs by < 1/256 of itself, and the smaller channels keep
  // the finer step, so every channel stays within 2^-8 of the largest.
  auto m = [&](double x) {
    return uint8_t(std::min(255.0, std::floor(std::ldexp(x, 8 - e) + 0.5)));
  };
  return {m(r), m(g), m(b), uint8_t(e + 128)};
}

Rgb decode_rgbe(const Rgbe& p) {
  if (p[3] == 0) return {};
  const int e = int(p[3]) - (128 + 8);
  return {float(std::ldexp(double(p[0]), e)), float(std::ldexp(double(p[1]), e)),
          float(std::ldexp(double(p[2]), e))};
}

void write_radiance_hdr(const std::string& path, int width, int height,
                        const std::vector<Rgbe>& pixels) {
  if (width <= 0 || height <= 0 || pixels.size() != size_t(width) * size_t(height)) {
    throw ColorError("cannot write " + path + ": bad image size");
  }
  std::vector<uint8_t> out;
  const std::string header = "#?RADIANCE\nSOFTWARE=tessera\nFORMAT=32-bit_rle_rgbe\n\n-Y " +
                             std::to_string(height) + " +X " + std::to_string(width) + "\n";
  out.insert(out.end(), header.begin(), header.end());
  const bool rle = width >= 8 && width <= 0x7fff;
  std::vector<uint8_t> planar(static_cast<size_t>(width));
  for (int y = 0; y < height; ++y) {
    const Rgbe* row = &pixels[size_t(y) * size_t(width)];
    if (!rle) {
      // Flat: unambiguous, because a nonzero pixel's largest mantissa is >= 128, so no pixel
      // can look like the (2, 2, <128) RLE marker or an old-style (1, 1, 1) repeat.
      for (int x = 0; x < width; ++x) out.insert(out.end(), row[x].begin(), row[x].end());
      continue;
    }
    out.insert(out.end(), {2, 2, uint8_t(width >> 8), uint8_t(width & 0xff)});
    for (int c = 0; c < 4; ++c) {
      for (int x = 0; x < width; ++x) planar[size_t(x)] = row[x][size_t(c)];
      encode_component_rle(planar.data(), width, out);
    }
  }
  std::ofstream f(path, std::ios::binary);
  f.write(reinterpret_cast<const char*>(out.data()), std::streamsize(out.size()));
  if (!f) throw ColorError("cannot write Radiance HDR " + path);
}

std::vector<Rgbe> read_radiance_hdr(const std::string& path, int* width, int* height) {
  std::ifstream f(path, std::ios::binary);
  if (!f) throw ColorError("cannot read Radiance HDR " + path);
  const std::vector<uint8_t> data((std::istreambuf_iterator<char>(f)),
                                  std::istreambuf_iterator<char>());
  const auto bad = [&](const char* why) { return ColorError(path + ": " + why); };
  // Header: lines up to an empty line, then the resolution line.
  size_t pos = 0;
  auto next_line = [&]() -> std::string {
    const size_t start = pos;
    while (pos < data.size() && data[pos] != '\n') ++pos;
    if (pos >= data.size()) throw bad("truncated header");
    return std::string(data.begin() + std::ptrdiff_t(start), data.begin() + std::ptrdiff_t(pos++));
  };
  if (next_line().rfind("#?", 0) != 0) throw bad("not a Radiance file (no #? line)");
  bool rgbe_format = false;
  for (std::string line = next_line(); !line.empty(); line = next_line()) {
    if (line == "FORMAT=32-bit_rle_rgbe") rgbe_format = true;
    if (line.rfind("FORMAT=", 0) == 0 && !rgbe_format) throw bad("not an RGBE file");
  }
  int w = 0, h = 0;
  if (std::sscanf(next_line().c_str(), "-Y %d +X %d", &h, &w) != 2 || w <= 0 || h <= 0 ||
      w > (1 << 16) || h > (1 << 16)) {
    throw bad("only -Y H +X W orientation is read");
  }
  std::vector<Rgbe> pixels(size_t(w) * size_t(h));
  std::vector<uint8_t> planar(size_t(w) * 4);
  auto need = [&](size_t n) {
    if (pos + n > data.size()) throw bad("truncated pixel data");
  };
  for (int y = 0; y < h; ++y) {
    Rgbe* row = &pixels[size_t(y) * size_t(w)];
    need(4);
    const bool rle = w >= 8 && w <= 0x7fff && data[pos] == 2 && data[pos + 1] == 2 &&
                     (data[pos + 2] & 0x80) == 0;
    if (!rle) {
      need(size_t(w) * 4);
      for (int x = 0; x < w; ++x, pos += 4) std::memcpy(row[x].data(), &data[pos], 4);
      continue;
    }
    if ((int(data[pos + 2]) << 8 | data[pos + 3]) != w) throw bad("scanline width mismatch");
    pos += 4;
    for (int c = 0; c < 4; ++c) {
      uint8_t* dst = &planar[size_t(c) * size_t(w)];
      int x = 0;
      while (x < w) {
        need(1);
        int count = data[pos++];
        if (count > 128) {
          count -= 128;
          need(1);
          if (x + count > w) throw bad("run overflows scanline");
          std::fill(dst + x, dst + x + count, data[pos++]);
        } else {
          if (count == 0 || x + count > w) throw bad("bad literal run");
          need(size_t(count));
          std::memcpy(dst + x, &data[pos], size_t(count));
          pos += size_t(count);
        }
        x += count;
      }
    }
    for (int x = 0; x < w; ++x) {
      for (int c = 0; c < 4; ++c) row[x][size_t(c)] = planar[size_t(c) * size_t(w) + size_t(x)];
    }
  }
  *width = w;
  *height = h;
  return pixels;
}

}  // namespace tessera::color
