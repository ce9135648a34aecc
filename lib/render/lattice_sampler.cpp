// SPDX-License-Identifier: Apache-2.0
#include "render/lattice_sampler.h"

#include <tbb/parallel_for.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <limits>

#include "render/integrator.h"
#include "render/ray_lanes.h"
#include "sampling/pass_plan.h"
#include "tile/bfloat16.h"

namespace tessera {

namespace {

// A pixel is smooth where the lattice's second differences at its corners are at most this many
// times the frame's target RMSE. For L quadratic across the pixel the corners' mean is off by
// (Lxx + Lyy) / 12, so a smooth pixel's own error stays below a sixth of the target; a step
// between two corners shows as a second difference of the step's height at both.
constexpr float kSmoothCurvature = 4.0f;

// A pixel whose corners pass the curvature test is still an edge pixel where this many of the
// eight pixels around it fail it. Where most pixels are edges (a checker's horizon, seen directly
// or in a mirror) a pixel's four corners agree mostly by chance: its true error is large, and the
// audit that finds it says (L - P)^2, which for a feature covering a fraction p of the pixel is
// 1/p times the squared error it bounds. On the Whitted showcase at 640x360 with its targets
// matched to POV-Ray's +A0.3 and +A0.03 (pov_compare, 8 seeds), the frame's estimate over its
// measured error was 1.00-1.09 and 1.12-1.92 without this rule, 0.99-1.02 and 1.01-1.22 with it
// at 4 (at 6: 1.09-1.93; at 3: the same honesty for 1.3-1.45x the camera rays), for 1.81 and 3.71
// camera rays a pixel against 1.76 and 3.89.
constexpr int kBusyNeighbours = 4;

// And where more than a quarter of the pixels of a region of 8 x 8 (aligned to the image) are
// edges, all of them are: the corners of a checker shrunk to a few pixels, or of a mesh's fine
// detail, agree by chance often enough that the pixels left smooth there held an error the
// target could not reach (320x180, --target-rmse: the bunny's floor stopped at 0.0106 and the
// showcase's horizon at 0.0024). With the rule, at 320x180, the bunny reaches 0.0105 with 414k
// camera rays (the sobol target: 489k) and 0.0051 with 976k (1.17M), the showcase 0.0020 with 783k
// (1.31M); the showcase at 640x360 at POV-Ray's +A0.3 error takes 12% more (482k against 431k).
// Regions of 4 x 4 left the error floors; a share of 0.15 cost 10% more everywhere, of 0.5 left
// the showcase's floor at 320x180.
constexpr int kRegion = 8;
constexpr double kRegionEdgeShare = 0.25;

// Audit probabilities: kAuditFloor for a flat pixel among smooth ones, rising linearly with its
// curvature to kAuditCeiling at the threshold, or with its edge neighbours to kAuditCeiling at
// eight, whichever is higher. Where most pixels are edges (a checker's horizon), a pixel whose
// four corners agree does so mostly by chance, and its error is a rare large term the audit must
// not leave to a 1-in-16 draw. Sub-pixel features the lattice missed sit in flat-looking pixels,
// so the floor is what catches them (in proportion to their area); the pixels near the threshold
// are where a smooth pixel's own error is largest.
constexpr float kAuditFloor = 1.0f / 16;
constexpr float kAuditCeiling = 0.5f;

// Keys of the lattice's and the audits' own random decisions (area-light samples along a corner's
// path, whether and where a pixel is audited), apart from every pixel sample's.
constexpr uint64_t kCornerKey = 0x6c61747469636531ULL;  // "lattice1"
constexpr uint64_t kAuditKey = 0x6175646974303031ULL;   // "audit001"

uint64_t corner_key(const ImageSettings& img, int frame, int cx, int cy) {
  return hash_combine(PixelSampler::pixel_key(img.seed, frame, cx, cy), kCornerKey);
}

float second_difference(const Rgb& a, const Rgb& b, const Rgb& c) {
  float m = 0;
  for (int k = 0; k < 3; ++k) m = std::max(m, std::abs(a[k] - 2.0f * b[k] + c[k]));
  return m;
}

// Traces corner rows [y0, y1) of the lattice into corners (row-major, width + 1 a row).
void trace_corner_rows(const RenderScene& scene, int y0, int y1, CornerLattice* corners, RayCounts* rays) {
  const ImageSettings& img = scene.image();
  const int cols = img.width + 1;
  constexpr int P = RenderScene::kPacket;
  float x[P], y[P];
  PixelSampler samplers[P];
  int n = 0;
  size_t first = size_t(y0) * size_t(cols);
  for (int cy = y0; cy < y1; ++cy) {
    for (int cx = 0; cx < cols; ++cx) {
      x[n] = float(cx);
      y[n] = float(cy);
      samplers[n] = PixelSampler(SamplerKind::kIndependent, corner_key(img, scene.frame(), cx, cy), 0, 1);
      if (++n == P || (cy == y1 - 1 && cx == cols - 1)) {
        trace_film_points(scene, x, y, samplers, n, &(*corners)[first], rays);
        first += size_t(n);
        n = 0;
      }
    }
  }
}

}  // namespace

void trace_film_points(const RenderScene& scene, const float* x, const float* y, const PixelSampler* samplers, int n,
                       Rgb* out, RayCounts* rays) {
  constexpr int P = RenderScene::kPacket;
  static_assert(P == kRayLanes);
  const ImageSettings& img = scene.image();
  const auto& cam = scene.camera();
  RayLanes r;  // camera rays: origin 0, tmax infinite
  std::fill(r.tmax, r.tmax + P, std::numeric_limits<float>::infinity());
  for (int at = 0; at < n; at += P) {
    const int m = std::min(P, n - at);
    for (int i = 0; i < m; ++i) {
      // The film position as render_samples makes it (render/pixel_samples.cpp).
      const float u = x[at + i] / float(img.width);
      const float v = y[at + i] / float(img.height);
      set_camera_direction(cam, u, v, &r, i);
    }
    rays->camera += uint64_t(m);
    trace_radiance_packet(scene, r, samplers + at, m, rays, out + at);
    for (int i = 0; i < m; ++i) {
      if (!is_finite(out[at + i])) {
        ++rays->nonfinite_samples;
        out[at + i] = Rgb(0.0f);
      }
    }
  }
}

float corner_curvature(const CornerLattice& corners, int width, int height, int px, int py) {
  // Too narrow for a second difference along an axis: no pixel can be called smooth.
  if (width < 2 || height < 2) return std::numeric_limits<float>::infinity();
  const int cols = width + 1;
  auto at = [&](int x, int y) -> const Rgb& { return corners[size_t(y) * size_t(cols) + size_t(x)]; };
  // Second differences centred on corner (x, y), along x and along y; moved one corner inwards on
  // the lattice's border.
  auto along_x = [&](int x, int y) {
    const int m = std::clamp(x, 1, width - 1);
    return second_difference(at(m - 1, y), at(m, y), at(m + 1, y));
  };
  auto along_y = [&](int x, int y) {
    const int m = std::clamp(y, 1, height - 1);
    return second_difference(at(x, m - 1), at(x, m), at(x, m + 1));
  };
  float m = 0;
  for (int y = py; y <= py + 1; ++y) m = std::max(m, std::min(along_x(px, y), along_x(px + 1, y)));
  for (int x = px; x <= px + 1; ++x) m = std::max(m, std::min(along_y(x, py), along_y(x, py + 1)));
  return m;
}

namespace {

// The audit of a smooth pixel: two independent positions uniform in it, drawn with probability
// q, and the product of their differences from the corners' bilinear interpolant P (mean over R,
// G, B). With e the pixel's error, the integral of L - P over it, each difference is an unbiased
// estimate of e and the two are independent, so their product is an unbiased estimate of e^2
// itself. One difference squared estimates E[(L - P)^2] instead, which bounds e^2 (Jensen) but
// 1/p times over for a feature covering a fraction p of the pixel: its estimate of the Cornell
// box was 2.3-7.6x the measured error, of the showcase at 320x180 up to 1.6x.
struct HoldOut {
  int px = 0, py = 0;
  float x[2] = {}, y[2] = {};
  float q = 0;
  double e2 = 0;
};

// The audits of the smooth pixels of rows [y0, y1) under `domain` (the key of their own draws),
// each pixel drawing one with probability q[p]; traced together, so that their packets are full.
// Their rays go to `rays`.
std::vector<HoldOut> hold_outs(const RenderScene& scene, const CornerLattice& corners, const LatticePilot& pilot,
                               const std::vector<float>& q, uint64_t domain, int y0, int y1, RayCounts* rays) {
  const ImageSettings& img = scene.image();
  const int W = img.width;
  std::vector<HoldOut> out;
  std::vector<float> x, y;
  std::vector<PixelSampler> samplers;
  for (int py = y0; py < y1; ++py) {
    for (int px = 0; px < W; ++px) {
      const size_t p = size_t(py) * size_t(W) + size_t(px);
      if (!pilot.smooth[p]) continue;
      const uint64_t key = hash_combine(PixelSampler::pixel_key(img.seed, scene.frame(), px, py), domain);
      uint64_t pick = mix64(key);
      if (!(to_unit_float(uint32_t(pick)) < q[p])) continue;
      HoldOut h;
      h.px = px, h.py = py, h.q = q[p];
      for (int i = 0; i < 2; ++i) {
        h.x[i] = float(px) + to_unit_float(uint32_t(pick >> 32));
        pick = mix64(pick);
        h.y[i] = float(py) + to_unit_float(uint32_t(pick));
        x.push_back(h.x[i]);
        y.push_back(h.y[i]);
        samplers.push_back(PixelSampler(SamplerKind::kIndependent, hash_combine(key, uint64_t(i)), 0, 1));
      }
      out.push_back(h);
    }
  }
  std::vector<Rgb> L(x.size());
  trace_film_points(scene, x.data(), y.data(), samplers.data(), int(x.size()), L.data(), rays);
  for (size_t k = 0; k < out.size(); ++k) {
    HoldOut& h = out[k];
    const auto c = [&](int dx, int dy) -> const Rgb& {
      return corners[size_t(h.py + dy) * size_t(W + 1) + size_t(h.px + dx)];
    };
    double d[2][3];
    for (int i = 0; i < 2; ++i) {
      // The bilinear interpolant of the corners at the sample's position.
      const float fx = h.x[i] - float(h.px), fy = h.y[i] - float(h.py);
      for (int ch = 0; ch < 3; ++ch) {
        const float top = c(0, 0)[ch] + (c(1, 0)[ch] - c(0, 0)[ch]) * fx;
        const float bottom = c(0, 1)[ch] + (c(1, 1)[ch] - c(0, 1)[ch]) * fx;
        d[i][ch] = double(L[2 * k + size_t(i)][ch]) - double(top + (bottom - top) * fy);
      }
    }
    for (int ch = 0; ch < 3; ++ch) h.e2 += d[0][ch] * d[1][ch] / 3.0;
  }
  return out;
}

// The smooth pixels of rows [y0, y1): their values (the corners' mean), and from their audits
// their variance estimates, in `out`; the audits' rays in `rays`. Returns how many were audited.
int64_t settle_smooth_band(const RenderScene& scene, const CornerLattice& corners, const std::vector<float>& q,
                           int y0, int y1, LatticePilot* out, RayCounts* rays) {
  const int W = scene.image().width;
  const std::vector<HoldOut> audits = hold_outs(scene, corners, *out, q, kAuditKey, y0, y1, rays);
  for (int py = y0; py < y1; ++py) {
    for (int px = 0; px < W; ++px) {
      const size_t p = size_t(py) * size_t(W) + size_t(px);
      if (!out->smooth[p]) continue;
      const auto c = [&](int dx, int dy) -> const Rgb& {
        return corners[size_t(py + dy) * size_t(W + 1) + size_t(px + dx)];
      };
      for (int ch = 0; ch < 3; ++ch) {
        out->rgb[3 * p + size_t(ch)] = ((c(0, 0)[ch] + c(1, 0)[ch]) + (c(0, 1)[ch] + c(1, 1)[ch])) * 0.25f;
      }
      out->spp[p] = 1;
    }
  }
  for (const HoldOut& h : audits) {
    const size_t p = size_t(h.py) * size_t(W) + size_t(h.px);
    // A negative product (the two differences of opposite signs) says the pixel's error is
    // small; a variance cannot be negative, so it stores 0.
    out->variance[p] = round_to_bfloat16(float(std::max(0.0, h.e2) / double(h.q)));
    out->spp[p] = 3;
  }
  return int64_t(audits.size());
}

// The statistics of block b (at bx, by, w x h) all of whose pixels are smooth.
BlockStat smooth_block_stat(const LatticePilot& pilot, int width, int b, int bx, int by, int w, int h) {
  BlockStat s;
  s.block = b;
  s.spp = 1;
  s.pixels = uint32_t(w * h);
  s.cost = 1;
  s.rate = first_rate(SamplerKind::kSobol);
  double sum = 0, mean[3] = {0, 0, 0};
  for (int y = by; y < by + h; ++y) {
    for (int x = bx; x < bx + w; ++x) {
      const size_t p = size_t(y) * size_t(width) + size_t(x);
      sum += double(pilot.variance[p]);
      for (int ch = 0; ch < 3; ++ch) mean[ch] += double(pilot.rgb[3 * p + size_t(ch)]);
    }
  }
  for (int ch = 0; ch < 3; ++ch) s.mean[size_t(ch)] = float(mean[ch] / double(w * h));
  s.mse = s.shape_mse = sum / double(w * h);
  return s;
}

}  // namespace

// Each second difference of the lattice is computed once here; corner_curvature takes eight a
// pixel, each shared with a neighbour, which was most of the classification's time.
void corner_curvature_rows(const CornerLattice& corners, int W, int H, int y0, int y1, float* curvature) {
  if (W < 2 || H < 2) {
    std::fill(curvature + size_t(y0) * size_t(W), curvature + size_t(y1) * size_t(W),
              std::numeric_limits<float>::infinity());
    return;
  }
  const int cols = W + 1;
  auto at = [&](int x, int y) -> const Rgb& { return corners[size_t(y) * size_t(cols) + size_t(x)]; };
  // Along x and along y at corners (x, y) for corner rows y0 .. y1, moved one corner inwards on
  // the lattice's border as corner_curvature does.
  const size_t rows = size_t(y1 - y0 + 1);
  std::vector<float> ax(rows * size_t(cols)), ay(rows * size_t(cols));
  for (int y = y0; y <= y1; ++y) {
    const int my = std::clamp(y, 1, H - 1);
    float* rx = &ax[size_t(y - y0) * size_t(cols)];
    float* ry = &ay[size_t(y - y0) * size_t(cols)];
    for (int x = 0; x < cols; ++x) {
      const int mx = std::clamp(x, 1, W - 1);
      rx[x] = second_difference(at(mx - 1, y), at(mx, y), at(mx + 1, y));
      ry[x] = second_difference(at(x, my - 1), at(x, my), at(x, my + 1));
    }
  }
  for (int py = y0; py < y1; ++py) {
    const float* top_x = &ax[size_t(py - y0) * size_t(cols)];
    const float* bottom_x = top_x + cols;
    const float* top_y = &ay[size_t(py - y0) * size_t(cols)];
    const float* bottom_y = top_y + cols;
    float* out = curvature + size_t(py) * size_t(W);
    for (int px = 0; px < W; ++px) {
      const float sides = std::max(std::max(std::min(top_x[px], top_x[px + 1]), std::min(bottom_x[px], bottom_x[px + 1])),
                                   std::max(std::min(top_y[px], bottom_y[px]), std::min(top_y[px + 1], bottom_y[px + 1])));
      out[px] = std::max(0.0f, sides);
    }
  }
}

namespace {

// The classification (the curvature test, then kBusyNeighbours and kRegion, all from the lattice
// alone, so no audit decides it) and every smooth pixel's audit probability, into pilot->smooth
// and q.
void classify(const CornerLattice& corners, int W, int H, float threshold, LatticePilot* pilot,
              std::vector<float>* q) {
  const size_t pixels = size_t(W) * size_t(H);
  q->resize(pixels);
  float* curvature = q->data();  // q is made from it in place, pixel by pixel, at the end
  constexpr int kBand = 8;
  const int bands = (H + kBand - 1) / kBand;
  tbb::parallel_for(0, bands, [&](int b) {
    const int y0 = b * kBand, y1 = std::min(H, y0 + kBand);
    corner_curvature_rows(corners, W, H, y0, y1, curvature);
    for (size_t p = size_t(y0) * size_t(W); p < size_t(y1) * size_t(W); ++p) pilot->smooth[p] = uint8_t(curvature[p] <= threshold);
  });
  // Edge pixels among each pixel's eight neighbours (and itself): column sums over three rows,
  // then sums of three columns.
  std::vector<uint8_t> edge_neighbours(pixels, 0);
  tbb::parallel_for(0, H, [&](int py) {
    std::vector<uint8_t> column(size_t(W) + 2, 0);
    for (int y = std::max(0, py - 1); y <= std::min(H - 1, py + 1); ++y) {
      const uint8_t* row = &pilot->smooth[size_t(y) * size_t(W)];
      for (int x = 0; x < W; ++x) column[size_t(x) + 1] += uint8_t(!row[x]);
    }
    uint8_t* out = &edge_neighbours[size_t(py) * size_t(W)];
    for (int x = 0; x < W; ++x) out[x] = uint8_t(column[size_t(x)] + column[size_t(x) + 1] + column[size_t(x) + 2]);
  });
  // Regions of kRegion x kRegion pixels (aligned to the image) where more than kRegionEdgeShare of
  // the pixels are edges are all edges.
  std::vector<uint8_t> busy_region(pixels, 0);
  for (int ry = 0; ry < H; ry += kRegion) {
    for (int rx = 0; rx < W; rx += kRegion) {
      const int x1 = std::min(W, rx + kRegion), y1 = std::min(H, ry + kRegion);
      int edges = 0;
      for (int y = ry; y < y1; ++y) {
        for (int x = rx; x < x1; ++x) edges += !pilot->smooth[size_t(y) * size_t(W) + size_t(x)];
      }
      if (!(double(edges) > kRegionEdgeShare * double((x1 - rx) * (y1 - ry)))) continue;
      for (int y = ry; y < y1; ++y) std::fill_n(&busy_region[size_t(y) * size_t(W) + size_t(rx)], x1 - rx, uint8_t(1));
    }
  }
  for (size_t p = 0; p < pixels; ++p) {
    if (edge_neighbours[p] >= kBusyNeighbours || busy_region[p]) pilot->smooth[p] = 0;
    const float busy = std::max(std::min(1.0f, curvature[p] / threshold), float(edge_neighbours[p]) / 8.0f);
    (*q)[p] = kAuditFloor + (kAuditCeiling - kAuditFloor) * busy;
  }
}

}  // namespace

LatticePilot render_lattice_pilot(const RenderScene& scene) {
  const ImageSettings& img = scene.image();
  const int W = img.width, H = img.height;
  const BlockGrid grid(W, H);
  constexpr int B = kAllocationBlock;
  LatticePilot out;
  const size_t pixels = size_t(W) * size_t(H);
  out.smooth.assign(pixels, 0);
  out.rgb.assign(3 * pixels, 0.0f);
  out.variance.assign(pixels, 0.0f);
  out.spp.assign(pixels, 0);
  out.frozen.blocks.assign(size_t(grid.count()), 0);
  out.frozen.frame_pixels = int64_t(pixels);
  out.stats.assign(size_t(grid.count()), BlockStat{});

  using Clock = std::chrono::steady_clock;
  auto since = [](Clock::time_point t) { return std::chrono::duration<double>(Clock::now() - t).count(); };
  auto stage = Clock::now();
  // The lattice, in bands of corner rows (each corner traced once: it is its own pure function).
  CornerLattice corners(size_t(W + 1) * size_t(H + 1));
  constexpr int kBand = 8;
  const int bands = (H + 1 + kBand - 1) / kBand;
  std::vector<RayCounts> band_rays(static_cast<size_t>(bands));
  tbb::parallel_for(0, bands, [&](int b) {
    trace_corner_rows(scene, b * kBand, std::min(H + 1, (b + 1) * kBand), &corners, &band_rays[size_t(b)]);
  });
  for (int b = 0; b < bands; ++b) out.rays += band_rays[size_t(b)];
  out.cost.corner_rays = out.rays.camera;
  out.cost.corner_seconds = since(stage);
  stage = Clock::now();

  const float threshold = kSmoothCurvature * float(img.target_rmse);
  std::vector<float> q;
  classify(corners, W, H, threshold, &out, &q);
  out.cost.classify_seconds = since(stage);
  stage = Clock::now();
  std::vector<RayCounts> row_rays(size_t(grid.rows));
  // Per row of blocks: settle the smooth pixels, and give the blocks all of whose pixels are
  // smooth their statistics.
  std::vector<int64_t> row_smooth(size_t(grid.rows), 0), row_audited(size_t(grid.rows), 0);
  tbb::parallel_for(0, grid.rows, [&](int row) {
    const int y0 = row * B, y1 = std::min(H, y0 + B);
    for (size_t p = size_t(y0) * size_t(W); p < size_t(y1) * size_t(W); ++p) row_smooth[size_t(row)] += out.smooth[p];
    row_audited[size_t(row)] = settle_smooth_band(scene, corners, q, y0, y1, &out, &row_rays[size_t(row)]);
    for (int col = 0; col < grid.cols; ++col) {
      const int bx = col * B, w = std::min(B, W - bx), b = row * grid.cols + col;
      bool all = true;
      for (int py = y0; py < y1; ++py) {
        for (int px = bx; px < bx + w; ++px) all = all && out.smooth[size_t(py) * size_t(W) + size_t(px)];
      }
      if (!all) continue;
      out.frozen.blocks[size_t(b)] = 1;
      out.stats[size_t(b)] = smooth_block_stat(out, W, b, bx, y0, w, y1 - y0);
    }
  });
  for (int row = 0; row < grid.rows; ++row) {
    out.rays += row_rays[size_t(row)];
    out.cost.audit_rays += row_rays[size_t(row)].camera;
    out.cost.smooth_pixels += row_smooth[size_t(row)];
    out.cost.audited_pixels += row_audited[size_t(row)];
  }
  out.cost.edge_pixels = int64_t(pixels) - out.cost.smooth_pixels;
  for (size_t p = 0; p < pixels; ++p) {
    if (out.smooth[p]) out.frozen.error += double(out.variance[p]);
  }
  out.cost.audit_seconds = since(stage);
  return out;
}

}  // namespace tessera
