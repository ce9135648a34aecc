// SPDX-License-Identifier: Apache-2.0
#include "rays/ray_npy.h"

#include <algorithm>
#include <cstring>
#include <fstream>
#include <limits>
#include <regex>
#include <vector>

#include "rays/rays_error.h"

namespace tessera::rays {

namespace {

constexpr char kMagic[] = "\x93NUMPY";

[[noreturn]] void fail(const std::string& path, const std::string& what) {
  throw RaysError(path + ": " + what);
}

// The header dictionary's value for `key` (a quoted string, True/False or a tuple), as text.
std::string header_value(const std::string& header, const std::string& key, const std::string& path) {
  const std::regex re("'" + key + "'\\s*:\\s*('[^']*'|True|False|\\([^)]*\\))");
  std::smatch m;
  if (!std::regex_search(header, m, re)) fail(path, "the .npy header has no '" + key + "'");
  return m[1].str();
}

template <class T>
void put(std::string* out, T v) {
  char b[sizeof(T)];
  std::memcpy(b, &v, sizeof(T));  // little-endian hosts only (x86-64, arm64), as the header says
  out->append(b, sizeof(T));
}

}  // namespace

RayTable read_rays_npy(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) fail(path, "cannot open");
  std::string bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  if (bytes.size() < 10 || bytes.compare(0, 6, kMagic, 6) != 0) fail(path, "not a .npy file (no \\x93NUMPY magic)");
  const int major = uint8_t(bytes[6]);
  size_t header_len = 0, header_at = 0;
  if (major == 1) {
    header_len = uint8_t(bytes[8]) | size_t(uint8_t(bytes[9])) << 8;
    header_at = 10;
  } else if (major == 2 || major == 3) {
    if (bytes.size() < 12) fail(path, "truncated header");
    for (int i = 0; i < 4; ++i) header_len |= size_t(uint8_t(bytes[8 + i])) << (8 * i);
    header_at = 12;
  } else {
    fail(path, ".npy format version " + std::to_string(major) + " is not supported");
  }
  if (bytes.size() < header_at + header_len) fail(path, "truncated header");
  const std::string header = bytes.substr(header_at, header_len);
  const std::string descr = header_value(header, "descr", path);
  if (header_value(header, "fortran_order", path) != "False") fail(path, "Fortran-order arrays are not supported");
  const bool f8 = descr == "'<f8'", f4 = descr == "'<f4'";
  if (!f8 && !f4) fail(path, "dtype " + descr + " is not supported (expected float64 '<f8' or float32 '<f4')");
  const std::string shape = header_value(header, "shape", path);
  std::smatch m;
  const std::regex two_d("\\(\\s*(\\d+)\\s*,\\s*(\\d+)\\s*\\)");
  if (!std::regex_match(shape, m, two_d)) fail(path, "shape " + shape + " is not 2-D (expected (n, 6), (n, 8) or (n, 9))");
  const size_t n = std::stoull(m[1].str()), cols = std::stoull(m[2].str());
  if (cols != 6 && cols != 8 && cols != 9) {
    fail(path, "shape " + shape + ": expected 6, 8 or 9 columns (ox,oy,oz,dx,dy,dz[,tmin,tmax[,id]])");
  }
  const size_t elem = f8 ? 8 : 4;
  const size_t data_at = header_at + header_len;
  if (n > (bytes.size() - data_at) / (cols * elem) || bytes.size() - data_at != n * cols * elem) {
    fail(path, "the data is " + std::to_string(bytes.size() - data_at) + " bytes, the shape needs " +
                   std::to_string(n * cols * elem));
  }
  auto value = [&](size_t i, size_t c) {
    const char* p = bytes.data() + data_at + (i * cols + c) * elem;
    if (f8) {
      double d;
      std::memcpy(&d, p, 8);
      return d;
    }
    float f;
    std::memcpy(&f, p, 4);
    return double(f);
  };
  RayTable t;
  t.rays.resize(n);
  if (cols == 9) t.ids.resize(n);
  for (size_t i = 0; i < n; ++i) {
    WorldRay& r = t.rays[i];
    r.o = Vec3d(value(i, 0), value(i, 1), value(i, 2));
    r.d = Vec3d(value(i, 3), value(i, 4), value(i, 5));
    if (cols >= 8) {
      r.tmin = float(value(i, 6));
      r.tmax = float(value(i, 7));
    }
    if (cols == 9) {
      const double id = value(i, 8);
      if (!(id >= 0 && id < 0x1p64 && id == double(uint64_t(id)))) {
        fail(path, "row " + std::to_string(i) + ": id " + std::to_string(id) + " is not an unsigned integer");
      }
      t.ids[i] = uint64_t(id);
    }
  }
  return t;
}

void write_hits_npy(const std::string& path, const RayTable& rays, const HitTable& h) {
  const bool ids = !rays.ids.empty();
  const std::vector<HitField> fields = h.occlusion ? std::vector<HitField>{} : h.fields.list();
  size_t obj_width = 1, mat_width = 1;
  for (const WorldHit& w : h.hits) {
    obj_width = std::max(obj_width, name_of(h.objects, w.object).size());
    mat_width = std::max(mat_width, name_of(h.materials, w.material).size());
  }
  // Each field's NumPy type: points are double, the rest of the floats single.
  auto dtype = [&](HitField field) -> std::string {
    switch (field) {
      case HitField::kPoint: return "<f8";
      case HitField::kObject: return "S" + std::to_string(obj_width);
      case HitField::kPrimitive: return "<i8";
      case HitField::kMaterial: return "S" + std::to_string(mat_width);
      default: return "<f4";
    }
  };
  std::string descr = "[";
  if (ids) descr += "('id', '<u8'), ";
  descr += "('hit', 'u1')";
  for (HitField field : fields) {
    for (std::string_view column : hit_field_columns(field)) {
      descr += ", ('" + std::string(column) + "', '" + dtype(field) + "')";
    }
  }
  descr += "]";
  std::string header = "{'descr': " + descr + ", 'fortran_order': False, 'shape': (" +
                       std::to_string(h.hits.size()) + ",), }";
  // Version 2.0 (4-byte header length) always: the descr can outgrow 1.0's 65535 bytes only
  // with absurd names, but one code path is simpler. Padded so the data starts 64-aligned.
  const size_t unpadded = 12 + header.size() + 1;
  header.append((64 - unpadded % 64) % 64, ' ');
  header += '\n';
  std::string out(kMagic, 6);
  out += char(2);
  out += char(0);
  put<uint32_t>(&out, uint32_t(header.size()));
  out += header;
  auto fixed = [&](const std::string& s, size_t width) { out += s + std::string(width - s.size(), '\0'); };
  for (size_t i = 0; i < h.hits.size(); ++i) {
    const WorldHit& w = h.hits[i];
    if (ids) put<uint64_t>(&out, rays.ids[i]);
    put<uint8_t>(&out, w.hit ? 1 : 0);
    for (HitField field : fields) {
      switch (field) {
        case HitField::kT:
          put<float>(&out, w.t);
          break;
        case HitField::kPoint:
          for (int k = 0; k < 3; ++k) put<double>(&out, w.p[k]);
          break;
        case HitField::kNormal:
          for (int k = 0; k < 3; ++k) put<float>(&out, w.n[k]);
          break;
        case HitField::kShadingNormal:
          for (int k = 0; k < 3; ++k) put<float>(&out, w.ns[k]);
          break;
        case HitField::kBarycentrics:
          put<float>(&out, w.u);
          put<float>(&out, w.v);
          break;
        case HitField::kObject:
          fixed(name_of(h.objects, w.object), obj_width);
          break;
        case HitField::kPrimitive:
          put<int64_t>(&out, w.hit ? int64_t(w.primitive) : -1);
          break;
        case HitField::kMaterial:
          fixed(name_of(h.materials, w.material), mat_width);
          break;
      }
    }
  }
  std::ofstream f(path, std::ios::binary);
  f.write(out.data(), std::streamsize(out.size()));
  if (!f) fail(path, "cannot write");
}

}  // namespace tessera::rays
