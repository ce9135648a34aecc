// SPDX-License-Identifier: Apache-2.0
// Measures the lossless EXR compressions `--exr-compression` offers on rendered frames: file size,
// CPU time to write and to read (one thread, the fastest of --repeat runs, so the figures are CPU
// cost per frame whatever the machine's cores), and that every pixel reads back bit for bit.
// Prints a Markdown table, then one JSON object per line (--json FILE writes them there instead).
//
//   exr_compression_bench [--work DIR] [--repeat N] [--json FILE] FRAME.exr [FRAME.exr ...]
#include <algorithm>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "../bench_host.h"
#include "image/exr_io.h"

using namespace tessera;
using bench::cpu_model;
using bench::process_cpu_seconds;
namespace fs = std::filesystem;

int main(int argc, char** argv) {
  fs::path work = fs::temp_directory_path() / "tessera_exr_compression_bench";
  int repeat = 3;
  std::string json_path;
  std::vector<std::string> frames;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    if (a == "--work" && i + 1 < argc) {
      work = argv[++i];
    } else if (a == "--repeat" && i + 1 < argc) {
      repeat = std::max(1, std::atoi(argv[++i]));
    } else if (a == "--json" && i + 1 < argc) {
      json_path = argv[++i];
    } else {
      frames.push_back(a);
    }
  }
  if (frames.empty()) {
    std::fprintf(stderr, "usage: exr_compression_bench [--work DIR] [--repeat N] [--json FILE] FRAME.exr ...\n");
    return 2;
  }
  fs::create_directories(work);
  set_exr_threads(1);
  std::vector<nlohmann::json> rows;
  try {
    for (const std::string& f : frames) {
      const ImageRGB img = read_exr(f);
      const double raw = double(img.rgb.size() * sizeof(float));
      std::printf("\n**%s** (%dx%d, 32-bit float RGB; one thread; fastest of %d)\n\n", fs::path(f).filename().c_str(),
                  img.width, img.height, repeat);
      std::printf("| compression | file MiB | of raw | write ms | read ms | bit-exact |\n|---|---:|---:|---:|---:|---|\n");
      for (const std::string& name : exr_compression_names()) {
        const fs::path out = work / (name + ".exr");
        double write_s = 1e30, read_s = 1e30;
        bool exact = true;
        for (int r = 0; r < repeat; ++r) {
          const double t0 = process_cpu_seconds();
          write_exr(out.string(), img, {}, ExrPixelType::kFloat, {}, parse_exr_compression(name));
          const double t1 = process_cpu_seconds();
          const ImageRGB back = read_exr(out.string());
          const double t2 = process_cpu_seconds();
          write_s = std::min(write_s, t1 - t0);
          read_s = std::min(read_s, t2 - t1);
          exact = exact && back.rgb.size() == img.rgb.size() &&
                  std::memcmp(back.rgb.data(), img.rgb.data(), img.rgb.size() * sizeof(float)) == 0;
        }
        const double bytes = double(fs::file_size(out));
        std::printf("| %s | %.2f | %.3f | %.0f | %.0f | %s |\n", name.c_str(), bytes / 1048576.0, bytes / raw,
                    write_s * 1e3, read_s * 1e3, exact ? "yes" : "**no**");
        rows.push_back({{"benchmark", "exr_compression"}, {"frame", fs::path(f).filename().string()},
                        {"width", img.width}, {"height", img.height}, {"compression", name},
                        {"bytes", int64_t(bytes)}, {"of_raw", bytes / raw}, {"write_cpu_s", write_s},
                        {"read_cpu_s", read_s}, {"bit_exact", exact}, {"cpu", cpu_model()}});
        fs::remove(out);
      }
    }
  } catch (const std::exception& e) {
    std::fprintf(stderr, "exr_compression_bench: %s\n", e.what());
    return 1;
  }
  std::FILE* js = json_path.empty() ? stdout : std::fopen(json_path.c_str(), "w");
  if (!js) {
    std::fprintf(stderr, "exr_compression_bench: cannot write %s\n", json_path.c_str());
    return 1;
  }
  if (json_path.empty()) std::printf("\n");
  for (const auto& r : rows) std::fprintf(js, "%s\n", r.dump().c_str());
  if (js != stdout) std::fclose(js);
  for (const auto& r : rows) {
    if (!r["bit_exact"].get<bool>()) return 1;  // a lossless codec that is not: the benchmark fails
  }
  return 0;
}
