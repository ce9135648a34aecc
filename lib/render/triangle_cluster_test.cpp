// SPDX-License-Identifier: Apache-2.0
#include "render/triangle_cluster.h"

#include <gtest/gtest.h>
#include <hwy/targets.h>

#include <algorithm>
#include <bit>
#include <cmath>
#include <iterator>
#include <limits>
#include <random>
#include <set>
#include <vector>

namespace tessera {
namespace {

TriangleCluster cluster_of(const std::vector<Vec3f>& v, size_t first, size_t count) {
  TriangleCluster c{};
  c.count = uint32_t(count);
  for (int lane = 0; lane < TriangleCluster::kSize; ++lane) {
    c.tri[lane] = lane < int(count) ? uint32_t(first) + uint32_t(lane) : UINT32_MAX;
    for (int k = 0; k < 3 && lane < int(count); ++k) {
      const Vec3f& p = v[3 * (first + size_t(lane)) + size_t(k)];
      c.v[k][0][lane] = p.x;
      c.v[k][1][lane] = p.y;
      c.v[k][2][lane] = p.z;
    }
  }
  return c;
}

// A closed octahedron-like fan: 8 triangles around vertex (0, 0, 1) and its mirror, sharing
// vertices and edges exactly, the case where a ray aimed at a vertex tests every tie.
std::vector<Vec3f> fan(float r) {
  const Vec3f top{0, 0, r}, bottom{0, 0, -r};
  std::vector<Vec3f> ring;
  for (int i = 0; i < 4; ++i) {
    const float a = float(i) * 1.5707964f;
    ring.push_back({r * std::cos(a), r * std::sin(a), 0.0f});
  }
  std::vector<Vec3f> v;
  for (int i = 0; i < 4; ++i) {
    const Vec3f a = ring[size_t(i)], b = ring[size_t((i + 1) % 4)];
    v.insert(v.end(), {top, a, b});
    v.insert(v.end(), {bottom, b, a});
  }
  return v;
}

// The meshes both lane tests run over: `count` clusters' worth of random triangles in [-4, 4]^3
// (seeded), then the fans of radii r1 and r2.
std::vector<std::vector<Vec3f>> test_meshes(unsigned seed, int count, float r1, float r2) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<float> x(-4, 4);
  std::vector<std::vector<Vec3f>> meshes;
  for (int m = 0; m < count; ++m) {
    std::vector<Vec3f> v;
    for (int i = 0; i < 3 * TriangleCluster::kSize; ++i) v.push_back({x(rng), x(rng), x(rng)});
    meshes.push_back(v);
  }
  meshes.push_back(fan(r1));
  meshes.push_back(fan(r2));
  return meshes;
}

// For every SIMD target this machine runs: each lane of intersect_cluster returns exactly
// (bit for bit) what the scalar watertight test returns for that triangle alone.
TEST(TriangleCluster, EveryLaneEqualsTheScalarTestOnEveryTarget) {
  std::uniform_real_distribution<float> x(-4, 4);
  std::uniform_int_distribution<int> count_of(1, TriangleCluster::kSize);
  const std::vector<std::vector<Vec3f>> meshes = test_meshes(7, 40, 1.0f, 3.7f);
  const std::vector<int64_t> targets = hwy::SupportedAndGeneratedTargets();
  ASSERT_FALSE(targets.empty());
  for (int64_t target : targets) {
    hwy::SetSupportedTargetsForTest(target);
    SCOPED_TRACE(hwy::TargetName(target));
    std::mt19937 rays(3);
    size_t hits = 0, tested = 0;
    for (const auto& mesh : meshes) {
      const size_t n = mesh.size() / 3 == TriangleCluster::kSize ? size_t(count_of(rays)) : mesh.size() / 3;
      const TriangleCluster c = cluster_of(mesh, 0, n);
      for (int r = 0; r < 400; ++r) {
        Vec3f o{x(rays), x(rays), x(rays)};
        // Half the rays aim at a vertex or an edge's midpoint of the cluster (exact ties).
        Vec3f aim{x(rays) * 0.25f, x(rays) * 0.25f, x(rays) * 0.25f};
        if (r % 2 == 0) {
          const size_t t = size_t(rays()) % n;
          const Vec3f& a = mesh[3 * t], &b = mesh[3 * t + 1];
          aim = r % 4 == 0 ? a : (a + b) * 0.5f;
        }
        const Vec3f d = normalize(aim - o);
        if (!(length(aim - o) > 0.0f)) continue;
        const float tnear = r % 3 == 0 ? 0.5f : 0.0f;
        const float tfar = r % 5 == 0 ? 2.0f : std::numeric_limits<float>::infinity();
        const int skip = r % 7 == 0 ? int(size_t(rays()) % n) : -1;
        const RayShear s = ray_shear(d);
        TriangleHit got[TriangleCluster::kSize];
        const uint32_t mask =
            intersect_cluster(c, cluster_ray(o, d), tnear, tfar, skip >= 0 ? c.tri[skip] : UINT32_MAX, got);
        for (size_t k = 0; k < TriangleCluster::kSize; ++k) {
          ++tested;
          TriangleHit want{};
          const bool expect = k < n && int(k) != skip &&
                              intersect_triangle_watertight(o, s, mesh[3 * k], mesh[3 * k + 1], mesh[3 * k + 2],
                                                            tnear, tfar, &want);
          ASSERT_EQ(bool(mask >> k & 1u), expect) << "ray " << r << " lane " << k;
          if (!expect) continue;
          ++hits;
          EXPECT_EQ(std::bit_cast<uint32_t>(got[k].t), std::bit_cast<uint32_t>(want.t));
          EXPECT_EQ(std::bit_cast<uint32_t>(got[k].u), std::bit_cast<uint32_t>(want.u));
          EXPECT_EQ(std::bit_cast<uint32_t>(got[k].v), std::bit_cast<uint32_t>(want.v));
        }
      }
    }
    EXPECT_GT(hits, tested / 50) << "too few hits to mean anything";
  }
  hwy::SetSupportedTargetsForTest(0);
}

// The triangle the ray leaves is named by its index, not its lane: a cluster of triangles
// 100..107 leaves out only the lane holding that index, and an index in no lane (or UINT32_MAX,
// which unused lanes hold) leaves out nothing.
TEST(TriangleCluster, SkipLeavesOutTheLaneHoldingThatTriangle) {
  const std::vector<Vec3f> mesh = fan(1.0f);
  TriangleCluster c = cluster_of(mesh, 0, 8);
  for (uint32_t k = 0; k < 8; ++k) c.tri[k] = 100 + k;
  const Vec3f o{0.01f, 0.02f, 5.0f}, d = normalize(Vec3f{0.0f, 0.0f, 0.0f} - o);  // at the top vertex
  const ClusterRay r = cluster_ray(o, d);
  const float inf = std::numeric_limits<float>::infinity();
  TriangleHit h[TriangleCluster::kSize];
  const uint32_t all = intersect_cluster(c, r, 0.0f, inf, UINT32_MAX, h);
  ASSERT_NE(all, 0u);
  EXPECT_EQ(intersect_cluster(c, r, 0.0f, inf, 99, h), all);
  EXPECT_EQ(intersect_cluster(c, r, 0.0f, inf, 108, h), all);
  for (uint32_t m = all; m != 0; m &= m - 1) {
    const int k = __builtin_ctz(m);
    EXPECT_EQ(intersect_cluster(c, r, 0.0f, inf, 100 + uint32_t(k), h), all & ~(1u << k)) << "lane " << k;
  }
}

// A packet's lanes, tested in one call, each give exactly what the one-ray test gives that lane's
// ray alone (so, by the test above, the scalar watertight test's bits), on every SIMD target:
// packets of 4, 8 and 16 lanes (Embree's widths), some lanes not valid or masked out (their
// entries untouched), directions along every axis and sign (the shear's axis choice made for all
// lanes at once), with ties between |d| components, zeros of either sign, and lanes leaving one of
// the triangles.
TEST(TriangleCluster, PacketLanesEqualTheOneRayTestOnEveryTarget) {
  std::uniform_real_distribution<float> x(-4, 4);
  const std::vector<std::vector<Vec3f>> meshes = test_meshes(17, 12, 1.0f, 2.5f);
  // Directions whose axis choice is delicate: on an axis, either sign, zeros of either sign, and
  // equal magnitudes on two or three axes.
  const std::vector<Vec3f> special = {
      {1, 0, 0}, {-1, 0, 0}, {0, 1, 0}, {0, -1, 0}, {0, 0, 1}, {0, 0, -1}, {-0.0f, 0.0f, -1}, {0.0f, -0.0f, 1},
      {0.6f, 0.6f, 0.2f}, {-0.6f, 0.6f, 0.2f}, {0.2f, -0.6f, 0.6f}, {0.6f, 0.2f, -0.6f}, {0.5f, -0.5f, -0.5f},
      {-0.5f, -0.5f, -0.5f}};
  const std::vector<int64_t> targets = hwy::SupportedAndGeneratedTargets();
  for (int64_t target : targets) {
    hwy::SetSupportedTargetsForTest(target);
    SCOPED_TRACE(hwy::TargetName(target));
    std::mt19937 rays(5);
    size_t hits = 0;
    for (unsigned N : {4u, 8u, 16u}) {
      for (const auto& mesh : meshes) {
        const TriangleCluster c = cluster_of(mesh, 0, TriangleCluster::kSize);
        for (int packet = 0; packet < 60; ++packet) {
          float f[8][ClusterPacket::kMaxLanes];  // org x y z, dir x y z, tnear, tfar
          uint32_t lanes = 0, skip[ClusterPacket::kMaxLanes], ray_mask[ClusterPacket::kMaxLanes];
          int valid[ClusterPacket::kMaxLanes];
          for (unsigned i = 0; i < N; ++i) {
            const Vec3f o{x(rays), x(rays), x(rays)};
            Vec3f d;
            if (rays() % 4 == 0) {
              d = special[size_t(rays()) % special.size()];
            } else {
              // Mostly aimed at a vertex or an edge's midpoint (hits and exact ties).
              const size_t t = size_t(rays()) % TriangleCluster::kSize;
              const Vec3f aim = rays() % 2 ? mesh[3 * t] : (mesh[3 * t] + mesh[3 * t + 1]) * 0.5f;
              d = normalize(aim - o);
            }
            f[0][i] = o.x, f[1][i] = o.y, f[2][i] = o.z, f[3][i] = d.x, f[4][i] = d.y, f[5][i] = d.z;
            f[6][i] = rays() % 3 == 0 ? 0.5f : 0.0f;
            f[7][i] = rays() % 5 == 0 ? 2.0f : std::numeric_limits<float>::infinity();
            skip[i] = rays() % 4 == 0 ? c.tri[rays() % TriangleCluster::kSize] : UINT32_MAX;
            // A quarter of the lanes not valid, an eighth whose ray mask misses the geometry's (2).
            valid[i] = rays() % 4 != 0 ? -1 : 0;
            ray_mask[i] = rays() % 8 == 0 ? 0xFFFFFFFDu : 0xFFFFFFFFu;
            if (valid[i] != 0 && ray_mask[i] & 2u) lanes |= 1u << i;
          }
          const auto leaving = [](const void* user, unsigned i) { return static_cast<const uint32_t*>(user)[i]; };
          const ClusterPacket p{f[0], f[1], f[2], f[3], f[4], f[5], f[6], f[7], ray_mask, valid, 2u, N, leaving, skip};
          uint32_t masks[ClusterPacket::kMaxLanes];
          std::fill(std::begin(masks), std::end(masks), 0xdeadbeefu);
          TriangleHit got[ClusterPacket::kMaxLanes][TriangleCluster::kSize];
          const uint32_t hit_lanes = intersect_cluster_packet(c, p, masks, got);
          for (unsigned i = 0; i < N; ++i) {
            if (!(lanes >> i & 1u)) {
              EXPECT_EQ(masks[i], 0xdeadbeefu) << "inactive lane " << i << " written";
              EXPECT_FALSE(hit_lanes >> i & 1u);
              continue;
            }
            const Vec3f o{f[0][i], f[1][i], f[2][i]}, d{f[3][i], f[4][i], f[5][i]};
            TriangleHit want[TriangleCluster::kSize];
            const uint32_t mask = intersect_cluster(c, cluster_ray(o, d), f[6][i], f[7][i], skip[i], want);
            ASSERT_EQ(masks[i], mask) << "N " << N << " packet " << packet << " lane " << i;
            EXPECT_EQ(bool(hit_lanes >> i & 1u), mask != 0) << "lane " << i;
            for (uint32_t m = mask; m != 0; m &= m - 1) {
              const int k = __builtin_ctz(m);
              ++hits;
              EXPECT_EQ(std::bit_cast<uint32_t>(got[i][k].t), std::bit_cast<uint32_t>(want[k].t));
              EXPECT_EQ(std::bit_cast<uint32_t>(got[i][k].u), std::bit_cast<uint32_t>(want[k].u));
              EXPECT_EQ(std::bit_cast<uint32_t>(got[i][k].v), std::bit_cast<uint32_t>(want[k].v));
            }
          }
        }
      }
    }
    EXPECT_GT(hits, 1000u) << "too few hits to mean anything";
  }
  hwy::SetSupportedTargetsForTest(0);
}

TEST(TriangleCluster, BuildPutsEveryTriangleInExactlyOneTightCluster) {
  // A 60 x 60 grid of quads (7200 triangles), shuffled so the input order says nothing.
  std::vector<Vec3f> v;
  for (int y = 0; y < 60; ++y) {
    for (int x = 0; x < 60; ++x) {
      const Vec3f a{float(x), float(y), 0}, b{float(x + 1), float(y), 0}, c{float(x), float(y + 1), 0},
          d{float(x + 1), float(y + 1), 0.5f};
      v.insert(v.end(), {a, b, d, a, d, c});
    }
  }
  std::mt19937 rng(5);
  std::vector<size_t> order(v.size() / 3);
  for (size_t i = 0; i < order.size(); ++i) order[i] = i;
  std::shuffle(order.begin(), order.end(), rng);
  std::vector<Vec3f> shuffled;
  for (size_t t : order) shuffled.insert(shuffled.end(), {v[3 * t], v[3 * t + 1], v[3 * t + 2]});

  const std::vector<TriangleCluster> clusters = build_triangle_clusters(shuffled.data(), order.size());
  std::set<uint32_t> seen;
  double area = 0;
  for (const TriangleCluster& c : clusters) {
    ASSERT_GE(c.count, 1u);
    ASSERT_LE(c.count, uint32_t(TriangleCluster::kSize));
    for (uint32_t k = 0; k < uint32_t(TriangleCluster::kSize); ++k) {
      if (k >= c.count) {
        EXPECT_EQ(c.tri[k], UINT32_MAX);
        continue;
      }
      EXPECT_TRUE(seen.insert(c.tri[k]).second) << "triangle " << c.tri[k] << " twice";
      for (int j = 0; j < 3; ++j) {
        const Vec3f& p = shuffled[3 * size_t(c.tri[k]) + size_t(j)];
        EXPECT_EQ(c.v[j][0][k], p.x);
        EXPECT_EQ(c.v[j][1][k], p.y);
        EXPECT_EQ(c.v[j][2][k], p.z);
        EXPECT_TRUE(p.x >= c.lower.x && p.y >= c.lower.y && p.z >= c.lower.z);
        EXPECT_TRUE(p.x <= c.upper.x && p.y <= c.upper.y && p.z <= c.upper.z);
      }
    }
    area += double(c.upper.x - c.lower.x) * double(c.upper.y - c.lower.y);
  }
  EXPECT_EQ(seen.size(), order.size());
  // Spatially tight: the clusters' boxes cover the 3600-unit grid a few times over at most
  // (random groups of 8 would cover it hundreds of times), and they are mostly full.
  EXPECT_LT(area, 4 * 3600.0);
  EXPECT_LT(clusters.size(), order.size() / 4);
  // Deterministic: the same input gives the same clusters.
  const std::vector<TriangleCluster> again = build_triangle_clusters(shuffled.data(), order.size());
  ASSERT_EQ(again.size(), clusters.size());
  for (size_t i = 0; i < clusters.size(); ++i) {
    for (int k = 0; k < TriangleCluster::kSize; ++k) EXPECT_EQ(again[i].tri[k], clusters[i].tri[k]);
  }
}

}  // namespace
}  // namespace tessera
