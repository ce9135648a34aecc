// SPDX-License-Identifier: Apache-2.0
// Unit tests of the coordinator's HTTP side without processes: the preview canvas, the
// Prometheus text, and the monitor feed's cost model (nothing kept while no page is open).
#include <gtest/gtest.h>

#include <cstring>
#include <filesystem>

#include "color/color_convert.h"
#include "color/png_io.h"
#include "coordinator.h"
#include "frame_canvas.h"
#include "metrics/farm_metrics.h"
#include "monitor_feed.h"

namespace tessera::server {
namespace {

namespace fs = std::filesystem;

// A tile whose pixels are all `value` (linear), rendered by `worker`.
tessera::v1::TileData tile(int index, int x0, int y0, int w, int h, float value, const std::string& worker) {
  tessera::v1::TileData t;
  t.set_tile_index(index);
  t.mutable_rect()->set_x0(x0);
  t.mutable_rect()->set_y0(y0);
  t.mutable_rect()->set_width(w);
  t.mutable_rect()->set_height(h);
  std::vector<float> rgb(size_t(w) * size_t(h) * 3, value);
  t.set_rgb(std::string(reinterpret_cast<const char*>(rgb.data()), rgb.size() * sizeof(float)));
  std::vector<float> variance(size_t(w) * size_t(h), 0.25f);
  t.set_variance(std::string(reinterpret_cast<const char*>(variance.data()), variance.size() * sizeof(float)));
  t.set_seconds(0.5);
  t.set_worker(worker);
  return t;
}

fs::path temp_dir() {
  std::string templ = (fs::temp_directory_path() / "tessera-monitor-XXXXXX").string();
  return mkdtemp(templ.data());
}

TEST(FrameCanvas, PlacesTilesMapsWorkersAndEncodesTheToneMappedFrame) {
  FrameCanvas canvas(20, 10, 16);  // tiles: (0,0) 16x10 and (16,0) 4x10
  ASSERT_EQ(canvas.tiles_x(), 2);
  ASSERT_EQ(canvas.tiles_y(), 1);
  EXPECT_EQ(canvas.add(tile(1, 16, 0, 4, 10, 0.5f, "w2")), "");
  EXPECT_EQ(canvas.worker_of(), (std::vector<int>{-1, 0}));
  // A second copy of a tile is ignored: the first one stays.
  EXPECT_EQ(canvas.add(tile(1, 16, 0, 4, 10, 0.9f, "w1")), "");
  EXPECT_EQ(canvas.tiles_done(), 1);
  // A tile that does not fit its rectangle is refused, by index.
  EXPECT_NE(canvas.add(tile(0, 0, 0, 16, 11, 0.5f, "w1")).find("tile 0"), std::string::npos);
  EXPECT_NE(canvas.add(tile(7, 0, 0, 16, 10, 0.5f, "w1")).find("outside"), std::string::npos);
  EXPECT_EQ(canvas.add(tile(0, 0, 0, 16, 10, 2.0f, "w1")), "");
  EXPECT_EQ(canvas.worker_of(), (std::vector<int>{1, 0}));
  EXPECT_EQ(canvas.workers(), (std::vector<std::string>{"w2", "w1"}));

  // The PNG decodes to what tonemap_to_rgb8 makes of the same pixels.
  const std::string png = canvas.png({});
  const fs::path dir = temp_dir();
  {
    FILE* f = std::fopen((dir / "p.png").c_str(), "wb");
    std::fwrite(png.data(), 1, png.size(), f);
    std::fclose(f);
  }
  const color::Rgb8Image got = color::read_png_rgb8((dir / "p.png").string());
  ImageRGB hdr(20, 10);
  for (int y = 0; y < 10; ++y) {
    for (int x = 0; x < 20; ++x) {
      for (int c = 0; c < 3; ++c) hdr.at(x, y)[c] = x < 16 ? 2.0f : 0.5f;
    }
  }
  const color::Rgb8Image want = color::tonemap_to_rgb8(hdr, {});
  EXPECT_EQ(got.pixels, want.pixels);
  EXPECT_EQ(got.pixels[0], 255);                  // 2.0 clamps to white
  EXPECT_EQ(got.pixels[3 * 16], want.pixels[48]);  // 0.5 linear is sRGB 188
  EXPECT_EQ(want.pixels[48], 188);
  fs::remove_all(dir);
}

struct CoordinatorFixture : ::testing::Test {
  fs::path dir = temp_dir();
  BundleStore bundles{dir};
  Coordinator coordinator{CoordinatorOptions{}, bundles, nullptr};
  ~CoordinatorFixture() override {
    coordinator.stop();
    fs::remove_all(dir);
  }
};

using FarmMetricsTest = CoordinatorFixture;

TEST_F(FarmMetricsTest, CountsEventsAndExportsLevelsInTheTextFormat) {
  FarmMetrics metrics(coordinator);
  const TileOutput out{std::make_shared<const std::string>("x"), 1000, 0.3};
  SchedulerListener& events = metrics;
  events.tile_finished({"j", 0, 0}, out, 1);
  events.tile_finished({"j", 0, 1}, out, 2);
  Lease lease;
  events.lease_ended(lease, LeaseEnd::kExpired);
  events.lease_ended(lease, LeaseEnd::kLostRace);
  events.lease_ended(lease, LeaseEnd::kCompleted);
  Assignment copy;
  copy.lease.speculative = true;
  events.tile_leased(copy);
  Assignment span;
  span.lease.count = 20;
  events.tile_leased(span);
  WorkerStats w;
  events.worker_faulted("j", w, "bad", 1, false);
  events.worker_faulted("j", w, "bad", 3, true);
  const std::string text = metrics.scrape();
  for (const char* line :
       {"tessera_tiles_completed_total 2\n", "tessera_rays_traced_total 2000\n", "tessera_lease_expiries_total 1\n",
        "tessera_speculative_lost_races_total 1\n", "tessera_speculative_copies_total 1\n",
        "tessera_leases_issued_total 2\n", "tessera_tiles_leased_total 21\n",
        "tessera_worker_faults_total 2\n", "tessera_worker_blocklistings_total 1\n",
        "tessera_tile_render_seconds_count 2\n", "tessera_tile_render_seconds_bucket{le=\"0.512\"} 2\n",
        "tessera_tile_render_seconds_bucket{le=\"0.256\"} 0\n", "tessera_jobs{state=\"running\"} 0\n",
        "tessera_tiles{state=\"queued\"} 0\n", "# TYPE tessera_tiles_completed_total counter\n",
        "# TYPE tessera_tile_render_seconds histogram\n"}) {
    EXPECT_NE(text.find(line), std::string::npos) << line << "in:\n" << text;
  }
}

// Ray servers announced to the coordinator: a gauge at each scrape, rows on the farm page.
TEST_F(FarmMetricsTest, RayServersInTheGaugeAndOnTheFarmPage) {
  FarmMetrics metrics(coordinator);
  MonitorFeed feed(coordinator);
  EXPECT_NE(metrics.scrape().find("tessera_ray_servers 0\n"), std::string::npos) << metrics.scrape();
  EXPECT_TRUE(feed.farm().at("ray_servers").empty());
  tessera::v1::RayServerAnnouncement a;
  a.mutable_server()->set_server_id("abc");
  a.mutable_server()->set_address("10.0.0.9:7879");
  a.mutable_server()->set_rays(1234);
  a.set_period_ms(60000);
  tessera::v1::RayServerAnnouncementAck ack;
  ASSERT_TRUE(coordinator.ray_servers().announce(a, "ipv4:10.0.0.9:5000", &ack).ok());
  EXPECT_NE(metrics.scrape().find("tessera_ray_servers 1\n"), std::string::npos) << metrics.scrape();
  const nlohmann::json rays = feed.farm().at("ray_servers");
  ASSERT_EQ(rays.size(), 1u);
  EXPECT_EQ(rays[0].at("address"), "10.0.0.9:7879");
  EXPECT_EQ(rays[0].at("rays"), 1234);
}

using MonitorFeedTest = CoordinatorFixture;

TEST_F(MonitorFeedTest, KeepsNothingWhileNoPageIsOpenAndEverythingOnceOneIs) {
  MonitorFeed feed(coordinator);
  SchedulerListener& events = feed;
  tessera::v1::TileData t = tile(0, 0, 0, 16, 16, 0.5f, "w1");
  t.set_job_id("j");
  const TileOutput out{std::make_shared<const std::string>(t.SerializeAsString()), 10, 0.5};
  // No page open: the tile is not looked at, nor kept.
  events.tile_finished({"j", 0, 0}, out, 1);
  EXPECT_EQ(out.payload.use_count(), 1);
  // A page polls: the feed is active from now on, and a tile arriving is queued for it...
  EXPECT_TRUE(feed.farm().at("jobs").empty());
  events.tile_finished({"j", 0, 0}, out, 1);
  EXPECT_EQ(out.payload.use_count(), 2);
  // ...and decoded by the next request (the job is not in the coordinator: no preview).
  feed.farm();
  EXPECT_EQ(out.payload.use_count(), 1);
  EXPECT_FALSE(feed.preview("j", std::nullopt, {}));
}

}  // namespace
}  // namespace tessera::server
