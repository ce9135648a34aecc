// SPDX-License-Identifier: Apache-2.0
// RayService over loopback gRPC: answers equal the in-process tracer's bit for bit, streams keep
// order, ids come back, bad input is INVALID_ARGUMENT naming the ray and field, tokens are
// checked; BundleScenes maps the coordinator's answers to the statuses clients see.
#include "ray_service.h"

#include <gtest/gtest.h>
#include <unistd.h>

#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>

#include "bundle_scenes.h"
#include "farm/bundle.h"
#include "farm/bundle_fetch.h"
#include "farm/channel.h"
#include "rays/parallel_trace.h"
#include "rays/ray_codec.h"
#include "scene/scene_parser.h"

namespace tessera::rayserver {
namespace {

namespace fs = std::filesystem;
namespace v1 = tessera::v1;
using namespace tessera::rays;  // lib/rays: the tracer the answers are checked against, the codec

constexpr const char* kHash = "aaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaa";
constexpr const char* kSceneJson = R"({"camera": {"position": [0, 0, -5], "look_at": [0, 0, 10]},
  "materials": {"red": {"type": "diffuse"}, "grey": {"type": "diffuse"}},
  "objects": [{"type": "sphere", "name": "ball", "center": [0, 0, 10], "radius": 2, "material": "red"},
              {"type": "plane", "name": "floor", "point": [0, -3, 0], "normal": [0, 1, 0], "material": "grey"}]})";

class RayServiceTest : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::temp_directory_path() / ("tessera_ray_service_test_" + std::to_string(::getpid()));
    fs::create_directories(dir_);
    std::ofstream(dir_ / "scene.json") << kSceneJson;
    auto scene = std::make_shared<const Scene>(load_scene((dir_ / "scene.json").string()));
    tracer_ = std::make_shared<const RayTracer>(scene, make_render_scene(*scene, 0));
  }
  void TearDown() override {
    if (server_) server_->Shutdown();
    fs::remove_all(dir_);
  }

  void start(RayServiceOptions options = {}, const std::string& client_token = "") {
    SceneSource source = [this](const std::string& sha, int frame, std::shared_ptr<const RayTracer>* t) {
      if (sha != kHash) return grpc::Status(grpc::StatusCode::INVALID_ARGUMENT, "scene.bundle_sha256: unknown bundle " + sha);
      *t = tracer_;
      return grpc::Status::OK;
    };
    service_ = std::make_unique<RayServiceImpl>(source, farm::Authenticator(client_token, ""), options);
    grpc::ServerBuilder b;
    int port = 0;
    b.AddListeningPort("127.0.0.1:0", grpc::InsecureServerCredentials(), &port);
    b.RegisterService(service_.get());
    server_ = b.BuildAndStart();
    ASSERT_GT(port, 0);
    address_ = "127.0.0.1:" + std::to_string(port);
  }
  std::unique_ptr<v1::RayService::Stub> stub(const std::string& token = "") {
    farm::ChannelSecurity sec;
    sec.token = token;
    return v1::RayService::NewStub(farm::make_coordinator_channel(address_, sec));
  }

  static v1::TraceRequest request(const std::vector<WorldRay>& rays, bool with_scene = true) {
    v1::TraceRequest req;
    if (with_scene) req.mutable_scene()->set_bundle_sha256(kHash);
    encode_rays(rays, {}, &req);
    return req;
  }
  grpc::Status trace(const v1::TraceRequest& req, v1::TraceResponse* resp) {
    grpc::ClientContext ctx;
    return stub()->Trace(&ctx, req, resp);
  }

  fs::path dir_;
  std::shared_ptr<const RayTracer> tracer_;
  std::unique_ptr<RayServiceImpl> service_;
  std::unique_ptr<grpc::Server> server_;
  std::string address_;
};

std::vector<WorldRay> fan(int n) {
  std::vector<WorldRay> rays;
  for (int i = 0; i < n; ++i) {
    const double a = -0.4 + 0.8 * i / std::max(1, n - 1);
    rays.push_back({{0, 0, 0}, normalize(Vec3d(a, a * 0.7 - 0.2, 1))});
  }
  return rays;
}

void expect_same(const std::vector<WorldHit>& got, const std::vector<WorldHit>& want) {
  ASSERT_EQ(got.size(), want.size());
  for (size_t i = 0; i < got.size(); ++i) {
    ASSERT_EQ(got[i].hit, want[i].hit) << i;
    ASSERT_EQ(std::memcmp(&got[i].t, &want[i].t, 4), 0) << i;
    ASSERT_EQ(got[i].p, want[i].p) << i;
    ASSERT_EQ(got[i].n, want[i].n) << i;
    ASSERT_EQ(got[i].ns, want[i].ns) << i;
    ASSERT_EQ(std::memcmp(&got[i].u, &want[i].u, 4), 0) << i;
    ASSERT_EQ(std::memcmp(&got[i].v, &want[i].v, 4), 0) << i;
    ASSERT_EQ(got[i].object, want[i].object) << i;
    ASSERT_EQ(got[i].primitive, want[i].primitive) << i;
    ASSERT_EQ(got[i].material, want[i].material) << i;
  }
}

std::vector<WorldHit> in_process(const RayTracer& tracer, const std::vector<WorldRay>& rays) {
  std::vector<WorldHit> hits(rays.size());
  tracer.nearest(rays.data(), rays.size(), hits.data());
  return hits;
}

TEST_F(RayServiceTest, TraceAnswersAsTheTracerDoesAndAnalytically) {
  start();
  v1::TraceResponse resp;
  ASSERT_TRUE(trace(request({{{0, 0, 0}, {0, 0, 1}}, {{0, 0, 0}, {0, -1, 0}}, {{0, 0, 0}, {0, 1, 0}}}), &resp).ok());
  const std::vector<WorldHit> hits = decode_hits(resp, 3, false);
  ASSERT_TRUE(hits[0].hit);
  EXPECT_FLOAT_EQ(hits[0].t, 8.0f);           // the sphere's near side
  EXPECT_EQ(hits[0].n, Vec3f(0, 0, -1));
  EXPECT_EQ(hits[0].object, 0u);
  ASSERT_TRUE(hits[1].hit);
  EXPECT_FLOAT_EQ(hits[1].t, 3.0f);           // the floor
  EXPECT_EQ(hits[1].object, 1u);
  EXPECT_EQ(tracer_->scene().materials[hits[1].material].name, "grey");
  EXPECT_EQ(tracer_->scene().materials[hits[0].material].name, "red");
  EXPECT_FALSE(hits[2].hit);
  EXPECT_TRUE(std::isinf(hits[2].t));
  EXPECT_EQ(hits[2].object, kNoIndex);

  const std::vector<WorldRay> rays = fan(500);
  ASSERT_TRUE(trace(request(rays), &resp).ok());
  std::vector<WorldHit> want(rays.size());
  tracer_->nearest(rays.data(), rays.size(), want.data());
  expect_same(decode_hits(resp, rays.size(), false), want);
}

TEST_F(RayServiceTest, ParallelBatchesEqualSerialOnes) {
  start({.max_batch_rays = 1 << 18, .threads = 4});
  const std::vector<WorldRay> rays = fan(10000);
  v1::TraceResponse resp;
  ASSERT_TRUE(trace(request(rays), &resp).ok());
  std::vector<WorldHit> want(rays.size());
  tracer_->nearest(rays.data(), rays.size(), want.data());
  expect_same(decode_hits(resp, rays.size(), false), want);
}

// The server decodes, traces and encodes a batch a chunk at a time, reusing its buffers (per
// thread, and a stream's messages): misses after hits, a batch of several chunks on one thread,
// and an occlusion batch after a nearest one all come back as the tracer's answers.
TEST_F(RayServiceTest, ReusedBuffersLeaveNothingBehind) {
  start({.max_batch_rays = 1 << 18, .threads = 1});
  std::vector<WorldRay> hits = fan(2 * kParallelBatch), misses = hits;
  for (WorldRay& r : misses) r.d = -r.d;  // up and away: no sphere, and the floor is behind
  grpc::ClientContext ctx;
  auto s = stub()->TraceStream(&ctx);
  ASSERT_TRUE(s->Write(request(hits)));
  ASSERT_TRUE(s->Write(request(misses, false)));
  v1::TraceRequest occ = request(hits, false);
  occ.set_occlusion(true);
  ASSERT_TRUE(s->Write(occ));
  ASSERT_TRUE(s->Write(request(fan(3), false)));
  s->WritesDone();
  v1::TraceResponse resp;
  ASSERT_TRUE(s->Read(&resp));
  expect_same(decode_hits(resp, hits.size(), false), in_process(*tracer_, hits));
  ASSERT_TRUE(s->Read(&resp));
  const std::vector<WorldHit> got = decode_hits(resp, misses.size(), false);
  EXPECT_FALSE(got[misses.size() / 2].hit);
  expect_same(got, in_process(*tracer_, misses));
  ASSERT_TRUE(s->Read(&resp));
  EXPECT_EQ(resp.t_size(), 0);
  std::vector<WorldHit> blocked(hits.size());
  tracer_->occluded(hits.data(), hits.size(), blocked.data());
  for (size_t i = 0; i < hits.size(); ++i) ASSERT_EQ(resp.hit()[i] != 0, blocked[i].hit) << i;
  ASSERT_TRUE(s->Read(&resp));
  expect_same(decode_hits(resp, 3, false), in_process(*tracer_, fan(3)));
  EXPECT_TRUE(s->Finish().ok());
}

TEST_F(RayServiceTest, OcclusionSendsOnlyTheFlags) {
  start();
  WorldRay blocked{{0, 0, 0}, {0, 0, 1}, 0.0f, 20.0f}, short_of_it{{0, 0, 0}, {0, 0, 1}, 0.0f, 7.5f};
  v1::TraceRequest req = request({blocked, short_of_it});
  req.set_occlusion(true);
  v1::TraceResponse resp;
  ASSERT_TRUE(trace(req, &resp).ok());
  EXPECT_EQ(resp.hit(), std::string("\1\0", 2));
  EXPECT_EQ(resp.t_size(), 0);
}

// Hits and misses: the fan meets the sphere and the floor; every third ray turned up and away.
std::vector<WorldRay> hits_and_misses(int n) {
  std::vector<WorldRay> rays = fan(n);
  for (size_t i = 0; i < rays.size(); i += 3) rays[i].d = -rays[i].d;
  return rays;
}

v1::TraceRequest with_fields(v1::TraceRequest req, std::initializer_list<int> fields) {
  for (int f : fields) req.add_fields(v1::HitField(f));
  return req;
}

// Which of the response's hit arrays are non-empty, by their proto names.
std::string filled(const v1::TraceResponse& r) {
  std::string s = r.hit().empty() ? "" : "hit";
  auto add = [&](const char* name, int size) {
    if (size) s += std::string(s.empty() ? "" : ",") + name;
  };
  add("t", r.t_size());
  add("points", r.points_size());
  add("normals", r.normals_size());
  add("shading_normals", r.shading_normals_size());
  add("barycentrics", r.barycentrics_size());
  add("objects", r.objects_size());
  add("primitives", r.primitives_size());
  add("materials", r.materials_size());
  add("ids", r.ids_size());
  return s;
}

template <class A>
bool same_bits(const A& got, const A& want) {
  return got.size() == want.size() &&
         std::memcmp(got.data(), want.data(), size_t(want.size()) * sizeof(*want.data())) == 0;
}

// A mask fills exactly the asked arrays, each equal bit for bit to the full answer's; repeats
// and any order are fine; ids come back whatever the mask.
TEST_F(RayServiceTest, AFieldMaskSendsOnlyTheAskedArraysWithTheFullAnswersBits) {
  start();
  const std::vector<WorldRay> rays = hits_and_misses(600);
  v1::TraceResponse full, resp;
  ASSERT_TRUE(trace(request(rays), &full).ok());
  ASSERT_EQ(filled(full), "hit,t,points,normals,shading_normals,barycentrics,objects,primitives,materials");
  size_t n_hit = 0;
  for (char c : full.hit()) n_hit += c != 0;
  ASSERT_GT(n_hit, 100u);
  ASSERT_LT(n_hit, 500u);

  ASSERT_TRUE(trace(with_fields(request(rays), {v1::HIT_FIELD_T}), &resp).ok());
  EXPECT_EQ(filled(resp), "hit,t");
  EXPECT_EQ(resp.hit(), full.hit());
  EXPECT_TRUE(same_bits(resp.t(), full.t()));

  ASSERT_TRUE(trace(with_fields(request(rays), {v1::HIT_FIELD_OBJECT, v1::HIT_FIELD_NORMAL, v1::HIT_FIELD_OBJECT}),
                    &resp)
                  .ok());
  EXPECT_EQ(filled(resp), "hit,normals,objects");
  EXPECT_EQ(resp.hit(), full.hit());
  EXPECT_TRUE(same_bits(resp.normals(), full.normals()));
  EXPECT_TRUE(same_bits(resp.objects(), full.objects()));

  // Every field named, in reverse order: the full answer, as with no mask.
  v1::TraceRequest all = request(rays);
  for (int f = v1::HIT_FIELD_MATERIAL; f >= v1::HIT_FIELD_T; --f) all.add_fields(v1::HitField(f));
  for (size_t i = 0; i < rays.size(); ++i) all.add_ids(7 * i);
  ASSERT_TRUE(trace(all, &resp).ok());
  EXPECT_EQ(filled(resp), filled(full) + ",ids");
  EXPECT_TRUE(same_bits(resp.points(), full.points()));
  EXPECT_TRUE(same_bits(resp.barycentrics(), full.barycentrics()));
  EXPECT_TRUE(same_bits(resp.materials(), full.materials()));

  // ids with a mask: still echoed.
  v1::TraceRequest t_ids = with_fields(request(rays), {v1::HIT_FIELD_PRIMITIVE});
  *t_ids.mutable_ids() = all.ids();
  ASSERT_TRUE(trace(t_ids, &resp).ok());
  EXPECT_EQ(filled(resp), "hit,primitives,ids");
  EXPECT_TRUE(same_bits(resp.primitives(), full.primitives()));
  EXPECT_TRUE(same_bits(resp.ids(), all.ids()));
}

TEST_F(RayServiceTest, AFieldMaskValueThatNamesNoFieldIsRefused) {
  start();
  const std::string allowed =
      "(allowed: HIT_FIELD_T, HIT_FIELD_POINT, HIT_FIELD_NORMAL, HIT_FIELD_SHADING_NORMAL, HIT_FIELD_BARYCENTRICS, "
      "HIT_FIELD_OBJECT, HIT_FIELD_PRIMITIVE, HIT_FIELD_MATERIAL)";
  auto refused = [&](const v1::TraceRequest& req) {
    v1::TraceResponse resp;
    const grpc::Status s = trace(req, &resp);
    EXPECT_EQ(s.error_code(), grpc::StatusCode::INVALID_ARGUMENT) << s.error_message();
    EXPECT_EQ(resp.hit().size(), 0u);  // nothing traced
    return s.error_message();
  };
  EXPECT_EQ(refused(with_fields(request(fan(4)), {v1::HIT_FIELD_T, 99})), "fields[1]: 99 is not a HitField " + allowed);
  EXPECT_EQ(refused(with_fields(request(fan(4)), {v1::HIT_FIELD_UNSPECIFIED})),
            "fields[0]: HIT_FIELD_UNSPECIFIED (0) names no field " + allowed);
  EXPECT_EQ(refused(with_fields(request(fan(4)), {v1::HIT_FIELD_T, v1::HIT_FIELD_POINT, -1})),
            "fields[2]: -1 is not a HitField " + allowed);
  // On occlusion queries too: the mask does not matter to the answer, but a bad one is bad.
  v1::TraceRequest occ = with_fields(request(fan(4)), {9});
  occ.set_occlusion(true);
  EXPECT_EQ(refused(occ), "fields[0]: 9 is not a HitField " + allowed);
}

// An occlusion query answers `hit` alone, whatever its mask asks for.
TEST_F(RayServiceTest, OcclusionWithAFieldMaskAnswersHitOnly) {
  start();
  WorldRay blocked{{0, 0, 0}, {0, 0, 1}, 0.0f, 20.0f}, short_of_it{{0, 0, 0}, {0, 0, 1}, 0.0f, 7.5f};
  v1::TraceRequest req = with_fields(request({blocked, short_of_it}), {v1::HIT_FIELD_T, v1::HIT_FIELD_OBJECT});
  req.set_occlusion(true);
  v1::TraceResponse resp;
  ASSERT_TRUE(trace(req, &resp).ok());
  EXPECT_EQ(resp.hit(), std::string("\1\0", 2));
  EXPECT_EQ(filled(resp), "hit");
}

// On a stream each request's mask is its own: the server's reused response carries nothing of
// the batch before (a full answer after a masked one, a masked one after a full one).
TEST_F(RayServiceTest, EachStreamRequestGetsItsOwnFieldMask) {
  start();
  const std::vector<WorldRay> rays = hits_and_misses(3000);  // over kParallelBatch: several chunks
  v1::TraceResponse full;
  ASSERT_TRUE(trace(request(rays), &full).ok());
  grpc::ClientContext ctx;
  auto s = stub()->TraceStream(&ctx);
  ASSERT_TRUE(s->Write(with_fields(request(rays), {v1::HIT_FIELD_T})));
  ASSERT_TRUE(s->Write(with_fields(request(rays, false), {v1::HIT_FIELD_OBJECT, v1::HIT_FIELD_NORMAL})));
  ASSERT_TRUE(s->Write(request(rays, false)));
  ASSERT_TRUE(s->Write(with_fields(request(rays, false), {v1::HIT_FIELD_BARYCENTRICS})));
  s->WritesDone();
  v1::TraceResponse resp;
  ASSERT_TRUE(s->Read(&resp));
  EXPECT_EQ(filled(resp), "hit,t");
  EXPECT_TRUE(same_bits(resp.t(), full.t()));
  ASSERT_TRUE(s->Read(&resp));
  EXPECT_EQ(filled(resp), "hit,normals,objects");
  EXPECT_TRUE(same_bits(resp.normals(), full.normals()));
  EXPECT_TRUE(same_bits(resp.objects(), full.objects()));
  ASSERT_TRUE(s->Read(&resp));
  EXPECT_EQ(filled(resp), filled(full));
  expect_same(decode_hits(resp, rays.size(), false), decode_hits(full, rays.size(), false));
  ASSERT_TRUE(s->Read(&resp));
  EXPECT_EQ(filled(resp), "hit,barycentrics");
  EXPECT_TRUE(same_bits(resp.barycentrics(), full.barycentrics()));
  EXPECT_EQ(resp.hit(), full.hit());
  EXPECT_TRUE(s->Finish().ok());
}

// The codec alone: HitArrays fills the asked arrays only, decode_hits reads them back into the
// asked fields and leaves the rest at WorldHit's defaults.
TEST(RayCodec, AMaskedAnswerRoundTrips) {
  std::vector<WorldHit> hits(5);
  for (size_t i = 0; i < hits.size(); ++i) {
    WorldHit& h = hits[i];
    h.hit = i % 2 == 0;
    h.t = 1.5f + float(i);
    h.p = Vec3d(1.0 / 3.0, double(i), -2.0);
    h.n = Vec3f(0, 1, 0);
    h.ns = Vec3f(0, 0, -1);
    h.u = 0.25f;
    h.v = 0.5f;
    h.object = uint32_t(i);
    h.primitive = uint32_t(100 + i);
    h.material = uint32_t(7 - i);
  }
  const HitFields mask = HitFields().with(HitField::kPoint).with(HitField::kMaterial);
  v1::TraceResponse resp;
  const HitArrays out(&resp, hits.size(), false, mask);
  out.write(3, std::span(hits).subspan(3));  // in any order of ranges
  out.write(0, std::span(hits).first(3));
  EXPECT_EQ(filled(resp), "hit,points,materials");
  const std::vector<WorldHit> back = decode_hits(resp, hits.size(), false, mask);
  const WorldHit defaults;
  for (size_t i = 0; i < hits.size(); ++i) {
    EXPECT_EQ(back[i].hit, hits[i].hit) << i;
    EXPECT_EQ(back[i].p, hits[i].p) << i;
    EXPECT_EQ(back[i].material, hits[i].material) << i;
    EXPECT_TRUE(std::isinf(back[i].t)) << i;
    EXPECT_EQ(back[i].n, defaults.n) << i;
    EXPECT_EQ(back[i].ns, defaults.ns) << i;
    EXPECT_EQ(back[i].u, 0.0f) << i;
    EXPECT_EQ(back[i].object, kNoIndex) << i;
    EXPECT_EQ(back[i].primitive, kNoIndex) << i;
  }
  // The mask on the request: nothing for every field (a request as before the mask), else each
  // asked field once, in order.
  v1::TraceRequest req;
  encode_fields(HitFields::all(), &req);
  EXPECT_EQ(req.fields_size(), 0);
  encode_fields(HitFields().with(HitField::kObject).with(HitField::kT), &req);
  ASSERT_EQ(req.fields_size(), 2);
  EXPECT_EQ(req.fields(0), v1::HIT_FIELD_T);
  EXPECT_EQ(req.fields(1), v1::HIT_FIELD_OBJECT);
  HitFields read;
  ASSERT_EQ(read_fields(req, &read), "");
  EXPECT_EQ(read, HitFields().with(HitField::kObject).with(HitField::kT));
  EXPECT_THROW(encode_fields(HitFields(), &req), RaysError);  // would read as every field
}

TEST(RayCodec, DecodeHitsThrowsOnAShortAskedArrayOnly) {
  std::vector<WorldHit> hits(4);
  v1::TraceResponse full;
  HitArrays(&full, hits.size(), false).write(0, hits);
  auto error = [](const v1::TraceResponse& r, HitFields mask) {
    try {
      decode_hits(r, 4, false, mask);
    } catch (const RaysError& e) {
      return std::string(e.what());
    }
    return std::string("no error");
  };
  const HitFields t = HitFields().with(HitField::kT), objects = HitFields().with(HitField::kObject);
  v1::TraceResponse r = full;
  r.mutable_t()->RemoveLast();
  EXPECT_EQ(error(r, t), "response field t has 3 values for 4 rays");
  EXPECT_EQ(error(r, HitFields::all()), "response field t has 3 values for 4 rays");
  EXPECT_EQ(error(r, objects), "no error");  // t not asked for: not read
  r = full;
  r.clear_objects();
  EXPECT_EQ(error(r, objects), "response field objects has 0 values for 4 rays");
  EXPECT_EQ(error(r, t), "no error");
  r = full;
  r.mutable_points()->RemoveLast();
  EXPECT_EQ(error(r, HitFields().with(HitField::kPoint)), "response field points has 11 values for 4 rays");
  r = full;
  r.mutable_hit()->pop_back();
  EXPECT_EQ(error(r, t), "response field hit has 3 values for 4 rays");
}

TEST_F(RayServiceTest, StreamAnswersEveryBatchInOrderWithItsIds) {
  start();
  grpc::ClientContext ctx;
  auto s = stub()->TraceStream(&ctx);
  for (int b = 0; b < 5; ++b) {
    v1::TraceRequest req = request(fan(10 + b), b == 0);  // the scene once, on the first batch
    for (int i = 0; i < 10 + b; ++i) req.add_ids(uint64_t(1000 * b + i));
    ASSERT_TRUE(s->Write(req));  // all five in flight before reading any answer
  }
  s->WritesDone();
  v1::TraceResponse resp;
  for (int b = 0; b < 5; ++b) {
    ASSERT_TRUE(s->Read(&resp)) << b;
    ASSERT_EQ(resp.ids_size(), 10 + b);
    EXPECT_EQ(resp.ids(0), uint64_t(1000 * b));
    EXPECT_EQ(decode_hits(resp, size_t(10 + b), false).size(), size_t(10 + b));
  }
  EXPECT_FALSE(s->Read(&resp));
  EXPECT_TRUE(s->Finish().ok());
}

TEST_F(RayServiceTest, BadInputIsInvalidArgumentNamingTheRayAndField) {
  start({.max_batch_rays = 100, .threads = 1});
  auto expect_refused = [&](const v1::TraceRequest& req, const std::string& text) {
    v1::TraceResponse resp;
    const grpc::Status s = trace(req, &resp);
    EXPECT_EQ(s.error_code(), grpc::StatusCode::INVALID_ARGUMENT) << text;
    EXPECT_NE(s.error_message().find(text), std::string::npos) << s.error_message();
    EXPECT_EQ(resp.hit().size(), 0u);  // nothing traced, no half answer
  };
  std::vector<WorldRay> rays = fan(10);
  rays[3].d = Vec3d(0, NAN, 1);
  expect_refused(request(rays), "ray 3: direction is not finite (field direction)");
  rays[3].d = Vec3d(0, 0, 0);
  expect_refused(request(rays), "ray 3: direction is zero-length");
  rays = fan(10);
  rays[7].tmin = 5;
  rays[7].tmax = 1;
  expect_refused(request(rays), "ray 7: t_min > t_max");
  rays[7].tmin = 0;
  rays[7].o.x = INFINITY;
  expect_refused(request(rays), "ray 7: origin is not finite");
  v1::TraceRequest req = request(fan(10));
  req.mutable_origins()->RemoveLast();
  expect_refused(req, "origins has 29 values; 10 rays (from directions) need 30");
  req = request(fan(10));
  req.add_t_max(1.0f);  // one t_max for ten rays
  expect_refused(req, "t_max has 1 values");
  expect_refused(request(fan(101)), "batch of 101 rays (directions / 3) is over this server's limit 100 (tessera-rays --max-batch-rays)");
  rays = fan(100);
  rays[98].tmin = NAN;  // the first bad ray is named, not a later one
  rays[99].d = Vec3d(0, 0, 0);
  expect_refused(request(rays), "ray 98: t_min must be finite and >= 0");
  req = request(fan(2));
  req.mutable_scene()->set_bundle_sha256(std::string(64, 'b'));
  expect_refused(req, "scene.bundle_sha256: unknown bundle bbbb");
  expect_refused(request(fan(2), false), "scene: required");
}

// check_rays() screens whole arrays at once and asks check_ray() only when something is wrong:
// for every kind of bad value, with and without t_min/t_max arrays, it names the first bad ray
// exactly as check_ray() over the decoded rays does.
TEST(RayCodec, CheckRaysNamesTheFirstBadRayAsCheckRayDoes) {
  const double bad_d[] = {NAN, INFINITY, -INFINITY, 2e30};
  const float bad_t[] = {NAN, -1.0f, INFINITY, -0.5f};
  for (int arrays = 0; arrays < 4; ++arrays) {
    for (int kind = 0; kind < 12; ++kind) {
      std::vector<WorldRay> rays = fan(50);
      for (WorldRay& r : rays) {
        if (arrays & 1) r.tmin = 0.25f;
        if (arrays & 2) r.tmax = 100.0f;
      }
      WorldRay& r = rays[size_t(7 + kind)];
      if (kind < 4) r.o[kind % 3] = bad_d[kind];
      else if (kind < 7) r.d[kind - 4] = bad_d[kind - 4];
      else if (kind == 7) r.d = Vec3d(0, 0, 0);
      else if (kind < 10) r.tmin = bad_t[kind - 8];
      else if (kind == 10) r.tmax = NAN;
      else r.tmin = 2 * r.tmax;
      v1::TraceRequest req;
      encode_rays(rays, {}, &req);
      std::string want;
      for (size_t i = 0; i < rays.size() && want.empty(); ++i) {
        WorldRay back;
        read_rays(req, i, i + 1, &back);
        std::string field;
        want = check_ray(back, i, &field);
        if (!want.empty()) want += " (field " + field + ")";
      }
      EXPECT_EQ(check_rays(req), want) << arrays << " " << kind;
    }
  }
  v1::TraceRequest good;
  encode_rays(fan(50), {}, &good);
  EXPECT_EQ(check_rays(good), "");
}

TEST_F(RayServiceTest, ABadBatchEndsTheStreamNamingIt) {
  start();
  grpc::ClientContext ctx;
  auto s = stub()->TraceStream(&ctx);
  ASSERT_TRUE(s->Write(request(fan(4))));
  std::vector<WorldRay> bad = fan(4);
  bad[2].d = Vec3d(0, 0, 0);
  s->Write(request(bad, false));
  s->WritesDone();
  v1::TraceResponse resp;
  EXPECT_TRUE(s->Read(&resp));  // the good first batch is answered
  EXPECT_FALSE(s->Read(&resp));
  const grpc::Status st = s->Finish();
  EXPECT_EQ(st.error_code(), grpc::StatusCode::INVALID_ARGUMENT);
  EXPECT_EQ(st.error_message(), "batch 1: ray 2: direction is zero-length (field direction)");
}

TEST_F(RayServiceTest, ClientTokenIsRequiredWhenConfigured) {
  start({}, "s3cret");
  v1::TraceResponse resp;
  grpc::ClientContext c1;
  EXPECT_EQ(stub()->Trace(&c1, request(fan(1)), &resp).error_code(), grpc::StatusCode::UNAUTHENTICATED);
  grpc::ClientContext c2;
  EXPECT_EQ(stub("wrong")->Trace(&c2, request(fan(1)), &resp).error_code(), grpc::StatusCode::UNAUTHENTICATED);
  grpc::ClientContext c3;
  EXPECT_TRUE(stub("s3cret")->Trace(&c3, request(fan(1)), &resp).ok());
  grpc::ClientContext c4;
  v1::SceneDescription d;
  EXPECT_EQ(stub()->DescribeScene(&c4, v1::SceneRef(), &d).error_code(), grpc::StatusCode::UNAUTHENTICATED);
}

TEST_F(RayServiceTest, DescribeSceneNamesObjectsAndMaterials) {
  start();
  grpc::ClientContext ctx;
  v1::SceneRef ref;
  ref.set_bundle_sha256(kHash);
  v1::SceneDescription d;
  ASSERT_TRUE(stub()->DescribeScene(&ctx, ref, &d).ok());
  EXPECT_EQ(std::vector<std::string>(d.objects().begin(), d.objects().end()), (std::vector<std::string>{"ball", "floor"}));
  EXPECT_EQ(std::vector<std::string>(d.object_kinds().begin(), d.object_kinds().end()),
            (std::vector<std::string>{"sphere", "plane"}));
  EXPECT_EQ(d.materials_size(), 2);
  EXPECT_EQ(d.frame_count(), 1);
  EXPECT_FALSE(d.embree_isa().empty());
}

TEST_F(RayServiceTest, BundleScenesMapsTheCoordinatorsAnswers) {
  const farm::BuiltBundle bundle = farm::make_bundle(dir_ / "scene.json", {});
  int fetches = 0;
  BundleScenes scenes(dir_ / "cache", [&](const std::string& sha) -> std::string {
    ++fetches;
    if (sha == bundle.sha256) return bundle.bytes;
    if (sha == std::string(64, 'c')) throw farm::FetchError(grpc::StatusCode::UNAVAILABLE, "connection refused");
    throw farm::FetchError(grpc::StatusCode::NOT_FOUND, "no such bundle");
  });
  std::shared_ptr<const RayTracer> t;
  ASSERT_TRUE(scenes.get(bundle.sha256, 0, &t).ok());
  WorldRay r{{0, 0, 0}, {0, 0, 1}};
  WorldHit h;
  t->nearest(&r, 1, &h);
  EXPECT_FLOAT_EQ(h.t, 8.0f);
  ASSERT_TRUE(scenes.get(bundle.sha256, 0, &t).ok());
  EXPECT_EQ(fetches, 1);  // fetched once, cached
  grpc::Status s = scenes.get(bundle.sha256, 1, &t);
  EXPECT_EQ(s.error_code(), grpc::StatusCode::INVALID_ARGUMENT);
  EXPECT_NE(s.error_message().find("scene.frame: 1 is not a frame"), std::string::npos) << s.error_message();
  s = scenes.get(std::string(64, 'd'), 0, &t);
  EXPECT_EQ(s.error_code(), grpc::StatusCode::INVALID_ARGUMENT);
  EXPECT_NE(s.error_message().find("scene.bundle_sha256: unknown bundle dddd"), std::string::npos);
  EXPECT_EQ(scenes.get(std::string(64, 'c'), 0, &t).error_code(), grpc::StatusCode::UNAVAILABLE);
  s = scenes.get("../etc/passwd", 0, &t);
  EXPECT_EQ(s.error_code(), grpc::StatusCode::INVALID_ARGUMENT);
  EXPECT_NE(s.error_message().find("is not a SHA-256"), std::string::npos);
}

}  // namespace
}  // namespace tessera::rayserver
