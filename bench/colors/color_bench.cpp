// SPDX-License-Identifier: Apache-2.0
// Measures every output format on rendered frames, and our palette quantizer against
// pngquant (run as an external program, never linked), printing Markdown tables.
//
//   color_bench [--work DIR] [--tonemap aces] FRAME.exr [FRAME.exr ...]
//
// Without frames it uses the synthetic render-like frame (and says so in the table).
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <string>
#include <vector>

#include "color/bmp565.h"
#include "color/color_convert.h"
#include "color/image_metrics.h"
#include "color/palette_quantizer.h"
#include "color/png_io.h"
#include "color/srgb.h"
#include "support/synthetic_images.h"
#include "image/exr_io.h"

using namespace tessera;
using namespace tessera::color;
namespace fs = std::filesystem;

namespace {

double seconds_since(std::chrono::steady_clock::time_point t0) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
}

std::string fmt(const char* f, double v) {
  char b[64];
  std::snprintf(b, sizeof(b), f, v);
  return b;
}

std::string psnr_cell(double psnr) { return std::isinf(psnr) ? "lossless" : fmt("%.2f", psnr); }

ImageRGB decode_png_srgb(const std::string& path) {
  const Rgb8Image png = read_png_rgb8(path);
  ImageRGB out(png.width, png.height);
  for (size_t i = 0; i < out.rgb.size(); ++i) out.rgb[i] = float(png.pixels[i]) / 255.0f;
  return out;
}

// The display image a written 8-bit/565/palette file holds, in linear light.
ImageRGB decode_ldr_linear(const std::string& path) {
  ImageRGB out;
  if (path.size() > 4 && path.substr(path.size() - 4) == ".bmp") {
    int w = 0, h = 0;
    const auto px = read_bmp565(path, &w, &h);
    out = ImageRGB(w, h);
    for (size_t i = 0; i < px.size(); ++i) {
      const Rgb c = unpack_565(px[i]);
      for (int k = 0; k < 3; ++k) out.rgb[3 * i + size_t(k)] = float(srgb_decode(c[k]));
    }
    return out;
  }
  out = decode_png_srgb(path);
  for (float& v : out.rgb) v = float(srgb_decode(v));
  return out;
}

struct Row {
  std::string label;
  ConvertOptions options;
  std::string file;
};

void format_table(const std::string& name, const ImageRGB& hdr, ToneMapOperator op,
                  const fs::path& work) {
  std::vector<Row> rows;
  auto add = [&](const char* label, OutputFormat f, const char* file,
                 DitherMethod d = DitherMethod::kNone, int colors = 256) {
    ConvertOptions o;
    o.format = f;
    o.tonemap.op = op;
    o.dither = d;
    o.colors = colors;
    rows.push_back({label, o, file});
  };
  add("rgba8 PNG", OutputFormat::kRgba8, "a.png");
  add("rgb8 PNG", OutputFormat::kRgb8, "b.png");
  add("rgb8 PNG, blue-noise", OutputFormat::kRgb8, "b2.png", DitherMethod::kBlueNoise);
  add("rgb565 BMP", OutputFormat::kRgb565, "c.bmp");
  add("rgb565 BMP, Bayer", OutputFormat::kRgb565, "c2.bmp", DitherMethod::kBayer);
  add("rgb565 BMP, blue-noise", OutputFormat::kRgb565, "c3.bmp", DitherMethod::kBlueNoise);
  add("palette 256 PNG", OutputFormat::kPalette, "d.png");
  add("palette 256 PNG, Floyd-Steinberg", OutputFormat::kPalette, "d2.png", DitherMethod::kFloydSteinberg);
  add("palette 16 PNG, Floyd-Steinberg", OutputFormat::kPalette, "d3.png", DitherMethod::kFloydSteinberg, 16);
  add("rgbe Radiance HDR (RLE)", OutputFormat::kRgbe, "e.hdr");
  add("rgb9e5 DDS", OutputFormat::kRgb9e5, "f.dds");
  add("exr-half (ZIP)", OutputFormat::kExrHalf, "g.exr");
  add("exr-float (ZIP)", OutputFormat::kExrFloat, "h.exr");
  std::printf("\n**%s** (%dx%d, tone map %s for the 8-bit formats and for the PSNR of HDR ones)\n\n",
              name.c_str(), hdr.width, hdr.height, std::string(tonemap_name(op)).c_str());
  std::printf("| format | bits/pixel | file size | file bits/pixel | PSNR dB | max abs err (/255) | "
              "max / mean rel err (linear) | banding (x1e-4) | encode ms |\n");
  std::printf("|---|---:|---:|---:|---:|---:|---:|---:|---:|\n");
  const ImageRGB display = tonemap_image(hdr, {op, 0.0f, 0.0f});
  for (const Row& r : rows) {
    // Best of three runs for the time; the file and errors are the same each run.
    ConversionReport rep;
    double best = 1e30;
    for (int i = 0; i < 3; ++i) {
      rep = convert_image(hdr, (work / r.file).string(), r.options);
      best = std::min(best, rep.encode_seconds);
    }
    const double px = double(hdr.width) * double(hdr.height);
    // Banding: RMS of the 9x9 box-filtered error in linear light (8-bit formats only).
    const std::string banding =
        rep.hdr ? "-"
                : fmt("%.2f", 1e4 * low_frequency_error(display, decode_ldr_linear((work / r.file).string()), 4));
    std::printf("| %s | %d | %.1f KiB | %.2f | %s | %.2f | %s | %s | %.0f |\n", r.label.c_str(),
                rep.bits_per_pixel, double(rep.file_bytes) / 1024.0, double(rep.file_bytes) * 8.0 / px,
                psnr_cell(rep.ldr.psnr_db).c_str(), rep.ldr.max_abs,
                rep.hdr ? (fmt("%.2e", rep.hdr->max_rel) + " / " + fmt("%.2e", rep.hdr->mean_rel)).c_str() : "-",
                banding.c_str(), best * 1e3);
  }
}

void palette_table(const std::string& name, const ImageRGB& hdr, ToneMapOperator op,
                   const fs::path& work) {
  // Both quantizers start from the same 8-bit sRGB PNG (what pngquant can read).
  const std::string ref_path = (work / "reference.png").string();
  convert_image(hdr, ref_path, ConvertOptions{{op, 0.0f, 0.0f}, OutputFormat::kRgb8, 256, DitherMethod::kNone});
  const ImageRGB ref = decode_png_srgb(ref_path);
  ImageRGB ref_linear(ref.width, ref.height);
  for (size_t i = 0; i < ref.rgb.size(); ++i) ref_linear.rgb[i] = float(srgb_decode(ref.rgb[i]));
  const bool have_pngquant = std::system("pngquant --version > /dev/null 2>&1") == 0;
  std::printf("\n**%s**: PSNR (dB) against the 8-bit PNG both start from, and wall time (ms)%s\n\n",
              name.c_str(), have_pngquant ? "" : " (pngquant not installed: its columns are empty)");
  std::printf("| colors | dither | ours PSNR | pngquant PSNR | difference | ours ms | pngquant ms |\n");
  std::printf("|---:|---|---:|---:|---:|---:|---:|\n");
  for (int n : {256, 64, 16}) {
    for (bool dither : {false, true}) {
      const auto t0 = std::chrono::steady_clock::now();
      const IndexedImage q = quantize_palette(
          ref_linear, {n, dither ? DitherMethod::kFloydSteinberg : DitherMethod::kNone, 16});
      const std::string ours_path = (work / ("ours_" + std::to_string(n) + ".png")).string();
      write_png_indexed(ours_path, q);
      const double ours_s = seconds_since(t0);
      const double ours = ldr_error(ref, decode_png_srgb(ours_path)).psnr_db;
      std::string theirs = "-", diff = "-", theirs_ms = "-";
      if (have_pngquant) {
        const std::string out = (work / ("pq_" + std::to_string(n) + ".png")).string();
        // pngquant's defaults (speed 4), --nofs for the undithered rows.
        const std::string cmd = "pngquant --force " + std::string(dither ? "" : "--nofs ") +
                                std::to_string(n) + " -o '" + out + "' '" + ref_path + "'";
        const auto t1 = std::chrono::steady_clock::now();
        const int rc = std::system(cmd.c_str());
        const double pq_s = seconds_since(t1);
        if (rc == 0) {
          const double pq = ldr_error(ref, decode_png_srgb(out)).psnr_db;
          theirs = fmt("%.2f", pq);
          diff = fmt("%+.2f", ours - pq);
          theirs_ms = fmt("%.0f", pq_s * 1e3);
        }
      }
      std::printf("| %d | %s | %.2f | %s | %s | %.0f | %s |\n", n,
                  dither ? "Floyd-Steinberg" : "none", ours, theirs.c_str(), diff.c_str(),
                  ours_s * 1e3, theirs_ms.c_str());
    }
  }
}

}  // namespace

int main(int argc, char** argv) {
  fs::path work = fs::temp_directory_path() / "tessera_color_bench";
  ToneMapOperator op = ToneMapOperator::kAces;
  std::vector<std::string> frames;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    if (a == "--work" && i + 1 < argc) {
      work = argv[++i];
    } else if (a == "--tonemap" && i + 1 < argc) {
      const auto t = parse_tonemap(argv[++i]);
      if (!t) {
        std::fprintf(stderr, "unknown tone map %s\n", argv[i]);
        return 2;
      }
      op = *t;
    } else {
      frames.push_back(a);
    }
  }
  fs::create_directories(work);
  try {
    std::vector<std::pair<std::string, ImageRGB>> images;
    for (const auto& f : frames) images.emplace_back(fs::path(f).filename().string(), read_exr(f));
    if (images.empty()) images.emplace_back("synthetic render-like frame", make_render_like(960, 540));
    std::printf("### Formats\n");
    for (const auto& [name, img] : images) format_table(name, img, op, work);
    std::printf("\n### Palette: ours against pngquant\n");
    for (const auto& [name, img] : images) palette_table(name, img, op, work);
  } catch (const std::exception& e) {
    std::fprintf(stderr, "color_bench: %s\n", e.what());
    return 1;
  }
  return 0;
}
