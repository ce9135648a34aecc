// SPDX-License-Identifier: Apache-2.0
// CSV and .npy reading and writing of rays and hits.
#include <gtest/gtest.h>
#include <unistd.h>

#include <cstring>
#include <filesystem>
#include <fstream>
#include <sstream>

#include "rays/ray_csv.h"
#include "rays/ray_npy.h"

namespace tessera::rays {
namespace {

namespace fs = std::filesystem;

TEST(RayCsv, ReadsColumnsInAnyOrderWithDefaults) {
  std::istringstream in("dz,dy,dx,oz,oy,ox,tmax,id\n1,0,0,3,2,1,5.5,42\n\n-1,0,0,0.1,0.2,0.30000000000000004,inf,7\n");
  const RayTable t = read_rays_csv(in, "rays.csv");
  ASSERT_EQ(t.rays.size(), 2u);
  EXPECT_EQ(t.rays[0].o, Vec3d(1, 2, 3));
  EXPECT_EQ(t.rays[0].d, Vec3d(0, 0, 1));
  EXPECT_EQ(t.rays[0].tmin, 0.0f);
  EXPECT_EQ(t.rays[0].tmax, 5.5f);
  EXPECT_EQ(t.rays[1].o.x, 0.30000000000000004);  // doubles read exactly
  EXPECT_TRUE(std::isinf(t.rays[1].tmax));
  EXPECT_EQ(t.ids, (std::vector<uint64_t>{42, 7}));
}

TEST(RayCsv, RefusesMalformedInputNamingLineAndColumn) {
  auto error = [](const std::string& text) {
    std::istringstream in(text);
    try {
      read_rays_csv(in, "r.csv");
    } catch (const RaysError& e) {
      return std::string(e.what());
    }
    return std::string("no error");
  };
  EXPECT_EQ(error(""), "r.csv: empty (expected a header row ox,oy,oz,dx,dy,dz)");
  EXPECT_EQ(error("ox,oy,oz,dx,dy\n"), "r.csv: the header has no column 'dz'");
  EXPECT_NE(error("ox,oy,oz,dx,dy,dz,colour\n").find("unknown column 'colour'"), std::string::npos);
  EXPECT_EQ(error("ox,oy,oz,dx,dy,dz\n0,0,0,0,0,1\n0,0,zero,0,0,1\n"),
            "r.csv line 3, column oz: 'zero' is not a number");
  EXPECT_EQ(error("ox,oy,oz,dx,dy,dz\n0,0,0,0,1\n"), "r.csv line 2: 5 columns, the header has 6");
  EXPECT_EQ(error("ox,oy,oz,dx,dy,dz,id\n0,0,0,0,0,1,-3\n"), "r.csv line 2, column id: '-3' is not an unsigned integer");
}

HitTable sample_hits() {
  HitTable h;
  h.objects = {"ball", ""};
  h.materials = {"red, shiny"};
  WorldHit a;
  a.hit = true;
  a.t = 0.1f;
  a.p = Vec3d(1.0 / 3.0, 2, 3);
  a.n = a.ns = Vec3f(0, 1, 0);
  a.object = 1;
  a.primitive = 12;
  a.material = 0;
  h.hits = {a, WorldHit{}};
  return h;
}

// The rays sample_hits() answers (their values do not matter to the writers), with `ids`.
RayTable two_rays(std::vector<uint64_t> ids) {
  RayTable rays;
  rays.rays.resize(2);
  rays.ids = std::move(ids);
  return rays;
}

TEST(RayCsv, WritesHitsThatReadBackBitForBit) {
  const RayTable rays = two_rays({5, 6});
  std::ostringstream out;
  write_hits_csv(out, rays, sample_hits());
  EXPECT_EQ(out.str(),
            "id,hit,t,px,py,pz,nx,ny,nz,snx,sny,snz,u,v,object,primitive,material\n"
            "5,1,0.100000001,0.33333333333333331,2,3,0,1,0,0,1,0,0,0,#1,12,\"red, shiny\"\n"
            "6,0,inf,0,0,0,0,0,0,0,0,0,0,0,,,\n");
  EXPECT_EQ(std::stof("0.100000001"), 0.1f);
  EXPECT_EQ(std::stod("0.33333333333333331"), 1.0 / 3.0);
}

// A field mask writes hit, the ids and exactly the asked fields' columns, in column order,
// with the values the full table has; occlusion writes hit alone whatever the mask.
TEST(RayCsv, WritesOnlyTheAskedFields) {
  RayTable rays = two_rays({5, 6});
  HitTable h = sample_hits();
  h.fields = parse_hit_fields("object,t,primitive");
  std::ostringstream out;
  write_hits_csv(out, rays, h);
  EXPECT_EQ(out.str(),
            "id,hit,t,object,primitive\n"
            "5,1,0.100000001,#1,12\n"
            "6,0,inf,,\n");
  h.fields = parse_hit_fields("point,barycentrics");
  rays.ids.clear();
  out.str("");
  write_hits_csv(out, rays, h);
  EXPECT_EQ(out.str(),
            "hit,px,py,pz,u,v\n"
            "1,0.33333333333333331,2,3,0,0\n"
            "0,0,0,0,0,0\n");
  h.occlusion = true;
  out.str("");
  write_hits_csv(out, rays, h);
  EXPECT_EQ(out.str(), "hit\n1\n0\n");
}

class RayNpy : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::temp_directory_path() / ("tessera_npy_test_" + std::to_string(::getpid()));
    fs::create_directories(dir_);
  }
  void TearDown() override { fs::remove_all(dir_); }
  // The bytes write_hits_npy() writes for `hits`, and where its header's text is.
  std::string written(const RayTable& rays, const HitTable& hits, std::string* header) {
    const fs::path p = dir_ / "out.npy";
    write_hits_npy(p.string(), rays, hits);
    std::ifstream in(p, std::ios::binary);
    const std::string bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
    uint32_t header_len = 0;
    if (bytes.size() >= 12) std::memcpy(&header_len, bytes.data() + 8, 4);
    *header = bytes.substr(std::min<size_t>(12, bytes.size()), header_len);
    return bytes;
  }
  // A version 1.0 .npy as NumPy writes it.
  fs::path write_npy(const std::string& descr, const std::string& shape, const std::string& data) {
    std::string header = "{'descr': '" + descr + "', 'fortran_order': False, 'shape': " + shape + ", }";
    header.append(63 - (10 + header.size()) % 64, ' ');
    header += '\n';
    std::string bytes = std::string("\x93NUMPY\x01\x00", 8);
    bytes += char(header.size() & 0xff);
    bytes += char(header.size() >> 8);
    const fs::path p = dir_ / "in.npy";
    std::ofstream(p, std::ios::binary) << bytes << header << data;
    return p;
  }
  fs::path dir_;
};

TEST_F(RayNpy, ReadsFloat64AndFloat32Arrays) {
  const double rows[2][9] = {{1, 2, 3, 0, 0, 1, 0.5, 9, 77}, {0, 0, 0, 1, 0, 0, 0, 1e30, 3}};
  RayTable t = read_rays_npy(write_npy("<f8", "(2, 9)", std::string(reinterpret_cast<const char*>(rows), sizeof rows)).string());
  ASSERT_EQ(t.rays.size(), 2u);
  EXPECT_EQ(t.rays[0].o, Vec3d(1, 2, 3));
  EXPECT_EQ(t.rays[0].tmin, 0.5f);
  EXPECT_EQ(t.rays[0].tmax, 9.0f);
  EXPECT_EQ(t.ids, (std::vector<uint64_t>{77, 3}));
  const float f[6] = {1, 2, 3, 0, 1, 0};
  t = read_rays_npy(write_npy("<f4", "(1, 6)", std::string(reinterpret_cast<const char*>(f), sizeof f)).string());
  ASSERT_EQ(t.rays.size(), 1u);
  EXPECT_EQ(t.rays[0].d, Vec3d(0, 1, 0));
  EXPECT_TRUE(std::isinf(t.rays[0].tmax));
  EXPECT_TRUE(t.ids.empty());
}

TEST_F(RayNpy, RefusesWhatItCannotRead) {
  auto error = [&](const std::string& descr, const std::string& shape, size_t bytes) {
    try {
      read_rays_npy(write_npy(descr, shape, std::string(bytes, '\0')).string());
    } catch (const RaysError& e) {
      return std::string(e.what());
    }
    return std::string("no error");
  };
  EXPECT_NE(error("<i4", "(1, 6)", 24).find("dtype '<i4' is not supported"), std::string::npos);
  EXPECT_NE(error("<f8", "(1, 7)", 56).find("expected 6, 8 or 9 columns"), std::string::npos);
  EXPECT_NE(error("<f8", "(6,)", 48).find("is not 2-D"), std::string::npos);
  EXPECT_NE(error("<f8", "(2, 6)", 95).find("the data is 95 bytes, the shape needs 96"), std::string::npos);
}

TEST_F(RayNpy, WritesAStructuredArray) {
  std::string header;
  const std::string bytes = written(two_rays({}), sample_hits(), &header);
  ASSERT_EQ(bytes.compare(0, 8, std::string("\x93NUMPY\x02\x00", 8)), 0);
  const size_t header_len = header.size();
  EXPECT_EQ((12 + header_len) % 64, 0u);  // data 64-byte aligned, as NumPy writes it
  EXPECT_NE(header.find("('object', 'S2')"), std::string::npos) << header;  // "#1" and "" 
  EXPECT_NE(header.find("'shape': (2,)"), std::string::npos);
  // One record: hit u1, t f4, p 3 f8, 8 f4, object S2, primitive i8, material S10.
  const size_t record = 1 + 4 + 24 + 32 + 2 + 8 + 10;
  ASSERT_EQ(bytes.size(), 12 + header_len + 2 * record);
  const char* r0 = bytes.data() + 12 + header_len;
  double px;
  std::memcpy(&px, r0 + 5, 8);
  EXPECT_EQ(px, 1.0 / 3.0);
  EXPECT_EQ(std::string(r0 + 61, 2), "#1");
  int64_t prim;
  std::memcpy(&prim, r0 + 63, 8);
  EXPECT_EQ(prim, 12);
  std::memcpy(&prim, r0 + record + 63, 8);
  EXPECT_EQ(prim, -1);  // a miss
}

TEST_F(RayNpy, WritesOnlyTheAskedFields) {
  HitTable h = sample_hits();
  h.fields = parse_hit_fields("primitive,t");
  std::string header;
  const std::string bytes = written(two_rays({5, 6}), h, &header);
  const size_t header_len = header.size();
  EXPECT_NE(header.find("'descr': [('id', '<u8'), ('hit', 'u1'), ('t', '<f4'), ('primitive', '<i8')], "),
            std::string::npos)
      << header;
  const size_t record = 8 + 1 + 4 + 8;
  ASSERT_EQ(bytes.size(), 12 + header_len + 2 * record);
  const char* r0 = bytes.data() + 12 + header_len;
  float t;
  std::memcpy(&t, r0 + 9, 4);
  EXPECT_EQ(t, 0.1f);
  int64_t prim;
  std::memcpy(&prim, r0 + 13, 8);
  EXPECT_EQ(prim, 12);
  std::memcpy(&prim, r0 + record + 13, 8);
  EXPECT_EQ(prim, -1);
}

}  // namespace
}  // namespace tessera::rays
