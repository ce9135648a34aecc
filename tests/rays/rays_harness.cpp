// SPDX-License-Identifier: Apache-2.0
#include "rays_harness.h"

#include <gtest/gtest.h>

#include <fstream>
#include <random>
#include <regex>
#include <thread>

#include "scene/scene_parser.h"

namespace tessera::farmtest {

using namespace std::chrono_literals;

std::string start_rays(Farm& farm, std::unique_ptr<Process>* proc, const std::vector<std::string>& extra,
                       const std::string& name) {
  std::vector<std::string> argv{(fs::path(TESSERA_BINARY_DIR) / "rays" / "tessera-rays").string(),
                                "--listen",      "127.0.0.1:0",
                                "--coordinator", farm.address(),
                                "--cache-dir",   (farm.dir() / (name + "-cache")).string(),
                                "--threads",     "2"};
  argv.insert(argv.end(), extra.begin(), extra.end());
  *proc = std::make_unique<Process>(argv, farm.dir() / (name + ".log"));
  const std::regex re("listening on (127\\.0\\.0\\.1:[0-9]+)");
  for (int i = 0; i < 1000; ++i) {
    std::smatch m;
    const std::string log = (*proc)->log();
    if (std::regex_search(log, m, re)) return m[1];
    if (!(*proc)->running()) break;
    std::this_thread::sleep_for(20ms);
  }
  ADD_FAILURE() << "tessera-rays did not start:\n" << (*proc)->log();
  return "";
}

void write_bunny_rays(const fs::path& path, int n) {
  const Scene scene = load_scene(source("scenes/bunny.json").string());
  const Vec3d eye = scene.camera.position, at = scene.camera.look_at;
  std::mt19937_64 rng(18);
  std::uniform_real_distribution<double> u(-1, 1);
  std::ofstream out(path);
  out.precision(17);
  out << "ox,oy,oz,dx,dy,dz,id\n";
  for (int i = 0; i < n; ++i) {
    Vec3d o = eye, d = normalize(at - eye) + Vec3d(u(rng), u(rng), u(rng)) * 0.15;
    if (i % 2) {
      o = at + Vec3d(u(rng), u(rng), u(rng)) * 2.0;
      d = Vec3d(u(rng), u(rng), u(rng));
    }
    out << o.x << ',' << o.y << ',' << o.z << ',' << d.x << ',' << d.y << ',' << d.z << ',' << i << '\n';
  }
}

bool eventually(const std::function<bool()>& done, std::chrono::milliseconds timeout) {
  const auto end = std::chrono::steady_clock::now() + timeout;
  while (!done()) {
    if (std::chrono::steady_clock::now() > end) return false;
    std::this_thread::sleep_for(20ms);
  }
  return true;
}

}  // namespace tessera::farmtest
