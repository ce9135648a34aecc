// SPDX-License-Identifier: Apache-2.0
// Fuzz target: the bundle reader (what the coordinator does with an uploaded bundle, and a worker
// with a fetched one). Parses, validates, extracts into a scratch directory and checks that
// nothing was written outside it. The only accepted failure is BundleError.
#include <stdlib.h>

#include <cstdint>
#include <cstdlib>
#include <filesystem>
#include <string>
#include <string_view>

#include <google/protobuf/stubs/logging.h>

#include "farm/bundle.h"
#include "tessera/v1/common.pb.h"

namespace fs = std::filesystem;

namespace {

// One scratch directory per process. Leaked on purpose: the exit handler that removes it runs
// after static destructors, so the path must not be a static object.
const fs::path& scratch() {
  static const fs::path* dir = [] {
    std::string templ = (fs::temp_directory_path() / "tessera-fuzz-bundle-XXXXXX").string();
    if (!mkdtemp(templ.data())) std::abort();
    auto* p = new fs::path(templ);
    std::atexit([] {
      std::error_code ec;
      fs::remove_all(*dir, ec);
    });
    return p;
  }();
  return *dir;
}

bool inside(const fs::path& p, const fs::path& dir) {
  const fs::path rel = p.lexically_normal().lexically_relative(dir.lexically_normal());
  return !rel.empty() && *rel.begin() != "..";
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  static const bool quiet = [] {
    google::protobuf::SetLogHandler(nullptr);  // invalid UTF-8 in a string field is logged, not a bug
    return true;
  }();
  (void)quiet;
  const std::string_view bytes(reinterpret_cast<const char*>(data), size);
  const fs::path& root = scratch();
  const fs::path dir = root / "b";
  try {
    tessera::v1::Bundle parsed;
    tessera::farm::parse_bundle(bytes, &parsed);
    const fs::path scene = tessera::farm::extract_bundle(bytes, dir);
    if (!inside(scene, dir) || !fs::is_regular_file(scene)) std::abort();
    for (const auto& f : parsed.files()) {
      if (!inside(dir / f.path(), dir) || !fs::is_regular_file(dir / f.path())) std::abort();
    }
  } catch (const tessera::farm::BundleError&) {
  }
  // Nothing but the extracted directory may appear in the scratch directory.
  for (const auto& e : fs::directory_iterator(root)) {
    if (e.path() != dir) std::abort();
  }
  std::error_code ec;
  fs::remove_all(dir, ec);
  return 0;
}
