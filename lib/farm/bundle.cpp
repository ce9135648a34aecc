// SPDX-License-Identifier: Apache-2.0
#include "farm/bundle.h"

#include <openssl/evp.h>

#include <algorithm>
#include <fstream>
#include <limits>
#include <set>
#include <sstream>

#include <google/protobuf/io/coded_stream.h>
#include <google/protobuf/io/zero_copy_stream_impl_lite.h>

#include "farm/temp_file.h"
#include "tessera/v1/common.pb.h"

namespace tessera::farm {

namespace fs = std::filesystem;

std::string sha256_hex(std::string_view bytes) {
  unsigned char digest[EVP_MAX_MD_SIZE];
  unsigned int len = 0;
  if (EVP_Digest(bytes.data(), bytes.size(), digest, &len, EVP_sha256(), nullptr) != 1) {
    throw BundleError("SHA-256 computation failed (OpenSSL)");
  }
  static const char* hex = "0123456789abcdef";
  std::string out;
  for (unsigned i = 0; i < len; ++i) {
    out += hex[digest[i] >> 4];
    out += hex[digest[i] & 15];
  }
  return out;
}

bool is_sha256_hex(std::string_view s) {
  if (s.size() != 64) return false;
  for (char c : s) {
    if (!((c >= '0' && c <= '9') || (c >= 'a' && c <= 'f'))) return false;
  }
  return true;
}

namespace {

std::string read_file(const fs::path& p) {
  std::ifstream in(p, std::ios::binary);
  if (!in) throw BundleError("cannot read " + p.string() + " (needed by the scene)");
  std::ostringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

void write_file(const fs::path& p, std::string_view data) {
  std::ofstream out(p, std::ios::binary | std::ios::trunc);
  out.write(data.data(), std::streamsize(data.size()));
  if (!out) throw BundleError("cannot write " + p.string());
}

// Name of the marker file recording which bundle entry is the scene.
constexpr const char* kSceneMarker = ".tessera-scene";

}  // namespace

bool is_safe_bundle_path(std::string_view path) {
  if (path.empty() || path.front() == '/' || path.find('\\') != std::string_view::npos) return false;
  // Longer names than any file system takes would fail half-way through extraction.
  if (path.size() > 1024) return false;
  // Control characters (NUL truncates the path for the OS, '\n' breaks the scene marker).
  for (char c : path) {
    if (static_cast<unsigned char>(c) < 0x20 || c == 0x7f) return false;
  }
  size_t start = 0;
  while (start <= path.size()) {
    size_t end = path.find('/', start);
    if (end == std::string_view::npos) end = path.size();
    const std::string_view part = path.substr(start, end - start);
    if (part.empty() || part == "." || part == ".." || part == kSceneMarker || part.size() > 255) return false;
    start = end + 1;
  }
  return true;
}

BuiltBundle make_bundle(const fs::path& scene_file, const std::vector<std::string>& dependencies) {
  const fs::path scene_abs = fs::weakly_canonical(fs::absolute(scene_file));
  std::vector<fs::path> files{scene_abs};
  for (const auto& d : dependencies) {
    // Two spellings of one file ("m/a.obj", "m/../m/a.obj"; two OBJ files naming one library)
    // are one entry: the loaders read the same bytes through either.
    const fs::path f = fs::weakly_canonical(scene_abs.parent_path() / d);
    if (std::find(files.begin(), files.end(), f) == files.end()) files.push_back(f);
  }
  // Deepest common directory of all files.
  fs::path root = scene_abs.parent_path();
  for (const auto& f : files) {
    while (!root.empty() && root != root.root_path()) {
      const auto rel = f.lexically_relative(root);
      if (!rel.empty() && *rel.begin() != "..") break;
      root = root.parent_path();
    }
  }
  tessera::v1::Bundle bundle;
  BuiltBundle out;
  for (size_t i = 0; i < files.size(); ++i) {
    const std::string rel = files[i].lexically_relative(root).generic_string();
    if (i == 0) bundle.set_scene_file(rel);
    auto* entry = bundle.add_files();
    entry->set_path(rel);
    entry->set_content(read_file(files[i]));
  }
  out.scene_file = bundle.scene_file();
  out.files = files.size();
  // Deterministic serialization: the same files always give the same hash from this client.
  {
    google::protobuf::io::StringOutputStream sos(&out.bytes);
    google::protobuf::io::CodedOutputStream cos(&sos);
    cos.SetSerializationDeterministic(true);
    bundle.SerializeToCodedStream(&cos);
  }
  out.sha256 = sha256_hex(out.bytes);
  return out;
}

void parse_bundle(std::string_view bytes, tessera::v1::Bundle* out) {
  tessera::v1::Bundle& bundle = *out;
  if (bytes.size() > size_t(std::numeric_limits<int>::max()) || !bundle.ParseFromArray(bytes.data(), int(bytes.size()))) {
    throw BundleError("not a tessera.v1.Bundle message");
  }
  if (!is_safe_bundle_path(bundle.scene_file())) {
    throw BundleError("bundle scene_file '" + bundle.scene_file() + "' is not a safe relative path");
  }
  std::set<std::string_view> paths;
  for (const auto& f : bundle.files()) {
    if (!is_safe_bundle_path(f.path())) {
      throw BundleError("bundle entry '" + f.path() + "' is not a safe relative path (absolute or '..')");
    }
    if (!paths.insert(f.path()).second) throw BundleError("bundle entry '" + f.path() + "' appears twice");
  }
  // A file that is also a directory of another entry cannot be extracted: refuse it here, as a
  // bad bundle, rather than as a std::filesystem error halfway through writing it.
  for (std::string_view p : paths) {
    for (size_t slash = p.find('/'); slash != std::string_view::npos; slash = p.find('/', slash + 1)) {
      if (paths.count(p.substr(0, slash))) {
        throw BundleError("bundle entry '" + std::string(p.substr(0, slash)) + "' is both a file and the directory of '" +
                          std::string(p) + "'");
      }
    }
  }
  if (!paths.count(bundle.scene_file())) {
    throw BundleError("bundle does not contain its scene file '" + bundle.scene_file() + "'");
  }
}

fs::path extract_bundle(std::string_view bytes, const fs::path& dir) {
  tessera::v1::Bundle bundle;
  parse_bundle(bytes, &bundle);
  if (fs::exists(extracted_scene_path(dir))) return extracted_scene_path(dir);

  fs::create_directories(dir.parent_path());
  fs::path tmp;
  try {
    tmp = make_temp_dir(dir.parent_path(), dir.filename().string() + ".tmp");
    for (const auto& f : bundle.files()) {
      const fs::path p = tmp / f.path();
      fs::create_directories(p.parent_path());
      write_file(p, f.content());
    }
    write_file(tmp / kSceneMarker, bundle.scene_file());
    std::error_code ec;
    fs::rename(tmp, dir, ec);
    if (ec) {
      fs::remove_all(tmp);  // someone else extracted it first: theirs is identical
      if (!fs::exists(dir / kSceneMarker)) throw BundleError("cannot create " + dir.string() + ": " + ec.message());
    }
  } catch (const fs::filesystem_error& e) {
    std::error_code ec;
    fs::remove_all(tmp, ec);
    throw BundleError(std::string("cannot extract the bundle: ") + e.what());
  } catch (...) {
    std::error_code ec;
    fs::remove_all(tmp, ec);
    throw;
  }
  return extracted_scene_path(dir);
}

fs::path extracted_scene_path(const fs::path& dir) {
  std::ifstream in(dir / kSceneMarker);
  std::string rel;
  if (!in || !std::getline(in, rel)) return dir / kSceneMarker;  // not extracted: a path that does not exist
  return dir / rel;
}

}  // namespace tessera::farm
