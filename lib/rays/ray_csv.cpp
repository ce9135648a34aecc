// SPDX-License-Identifier: Apache-2.0
#include "rays/ray_csv.h"

#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <istream>
#include <limits>
#include <map>
#include <ostream>
#include <sstream>
#include <vector>

#include "rays/rays_error.h"

namespace tessera::rays {

namespace {

std::vector<std::string> split_csv_line(const std::string& line) {
  std::vector<std::string> cells;
  std::string cell;
  for (char c : line) {
    if (c == ',') {
      cells.push_back(cell);
      cell.clear();
    } else if (c != '\r' && c != ' ' && c != '\t') {
      cell += c;
    }
  }
  cells.push_back(cell);
  return cells;
}

// A CSV cell quoted when it could break the row (object names are the scene author's text).
std::string csv_cell(const std::string& s) {
  if (s.find_first_of(",\"\n\r") == std::string::npos) return s;
  std::string q = "\"";
  for (char c : s) q += c == '"' ? std::string("\"\"") : std::string(1, c);
  return q + "\"";
}

enum Column { kOx, kOy, kOz, kDx, kDy, kDz, kTmin, kTmax, kId, kColumns };
const char* const kNames[kColumns] = {"ox", "oy", "oz", "dx", "dy", "dz", "tmin", "tmax", "id"};

}  // namespace

RayTable read_rays_csv(std::istream& in, const std::string& source) {
  std::string line;
  if (!std::getline(in, line)) throw RaysError(source + ": empty (expected a header row ox,oy,oz,dx,dy,dz)");
  const std::vector<std::string> header = split_csv_line(line);
  int where[kColumns];
  std::fill(where, where + kColumns, -1);
  for (size_t i = 0; i < header.size(); ++i) {
    int c = 0;
    while (c < kColumns && header[i] != kNames[c]) ++c;
    if (c == kColumns) {
      throw RaysError(source + ": unknown column '" + header[i] +
                      "' in the header (expected ox,oy,oz,dx,dy,dz and optionally tmin,tmax,id)");
    }
    if (where[c] >= 0) throw RaysError(source + ": column '" + header[i] + "' appears twice");
    where[c] = int(i);
  }
  for (int c = kOx; c <= kDz; ++c) {
    if (where[c] < 0) throw RaysError(source + ": the header has no column '" + kNames[c] + "'");
  }
  RayTable t;
  size_t line_no = 1;
  while (std::getline(in, line)) {
    ++line_no;
    if (line.find_first_not_of(" \t\r") == std::string::npos) continue;  // blank lines
    const std::vector<std::string> cells = split_csv_line(line);
    if (cells.size() != header.size()) {
      throw RaysError(source + " line " + std::to_string(line_no) + ": " + std::to_string(cells.size()) +
                      " columns, the header has " + std::to_string(header.size()));
    }
    double v[kColumns] = {0, 0, 0, 0, 0, 0, 0, std::numeric_limits<double>::infinity(), 0};
    uint64_t id = 0;
    for (int c = 0; c < kColumns; ++c) {
      if (where[c] < 0) continue;
      const std::string& s = cells[size_t(where[c])];
      char* end = nullptr;
      errno = 0;
      if (c == kId) id = std::strtoull(s.c_str(), &end, 10);
      else v[c] = std::strtod(s.c_str(), &end);  // accepts inf, nan: check_ray judges values
      if (s.empty() || *end != '\0' || (c == kId && (errno == ERANGE || s[0] == '-'))) {
        throw RaysError(source + " line " + std::to_string(line_no) + ", column " + kNames[c] + ": '" + s +
                        "' is not " + (c == kId ? "an unsigned integer" : "a number"));
      }
    }
    WorldRay r;
    r.o = Vec3d(v[kOx], v[kOy], v[kOz]);
    r.d = Vec3d(v[kDx], v[kDy], v[kDz]);
    r.tmin = float(v[kTmin]);
    r.tmax = float(v[kTmax]);
    t.rays.push_back(r);
    if (where[kId] >= 0) t.ids.push_back(id);
  }
  return t;
}

void write_hits_csv(std::ostream& out, const RayTable& rays, const HitTable& h) {
  const bool ids = !rays.ids.empty();
  const std::vector<HitField> fields = h.occlusion ? std::vector<HitField>{} : h.fields.list();
  out << (ids ? "id," : "") << "hit";
  for (HitField field : fields) {
    for (std::string_view column : hit_field_columns(field)) out << ',' << column;
  }
  out << "\n";
  char buf[64];
  // %.9g and %.17g read back as the same float and double.
  auto f = [&](float x) {
    std::snprintf(buf, sizeof buf, "%.9g", double(x));
    out << ',' << buf;
  };
  auto d = [&](double x) {
    std::snprintf(buf, sizeof buf, "%.17g", x);
    out << ',' << buf;
  };
  for (size_t i = 0; i < h.hits.size(); ++i) {
    const WorldHit& w = h.hits[i];
    if (ids) out << rays.ids[i] << ',';
    out << (w.hit ? 1 : 0);
    for (HitField field : fields) {
      switch (field) {
        case HitField::kT:
          f(w.t);
          break;
        case HitField::kPoint:
          for (int k = 0; k < 3; ++k) d(w.p[k]);
          break;
        case HitField::kNormal:
          for (int k = 0; k < 3; ++k) f(w.n[k]);
          break;
        case HitField::kShadingNormal:
          for (int k = 0; k < 3; ++k) f(w.ns[k]);
          break;
        case HitField::kBarycentrics:
          f(w.u);
          f(w.v);
          break;
        case HitField::kObject:
          out << ',' << csv_cell(name_of(h.objects, w.object));
          break;
        case HitField::kPrimitive:
          out << ',';
          if (w.hit) out << w.primitive;  // empty for a miss
          break;
        case HitField::kMaterial:
          out << ',' << csv_cell(name_of(h.materials, w.material));
          break;
      }
    }
    out << '\n';
  }
}

}  // namespace tessera::rays
