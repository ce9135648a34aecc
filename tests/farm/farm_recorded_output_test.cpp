// SPDX-License-Identifier: Apache-2.0
// A job carries its output: `tessera submit -o PATTERN` records the pattern (made absolute) and
// the frame output options with the job, and a later `tessera watch JOB` without -o, from any
// directory and after a coordinator kill -9 and restart, writes the frames there, as asked.
// Real processes on loopback (farm_harness.h).
#include <gtest/gtest.h>

#include <nlohmann/json.hpp>

#include "farm_harness.h"

namespace tessera::farmtest {
namespace {

const fs::path kScene = source("tests/farm/whitted_orbit.json");  // 3 frames, 96x64

std::string frame_name(const char* stem, int frame, const char* ext) {
  char name[64];
  std::snprintf(name, sizeof name, "%s_%04d.%s", stem, frame, ext);
  return name;
}

TEST(FarmRecordedOutput, ADetachedJobsFramesLandWhereSubmitRecordedThemWhoeverWatchesLater) {
  Farm farm;
  farm.start_server();
  farm.start_worker("w", 2);
  const fs::path share = farm.dir() / "share";
  // Two jobs: tone-mapped PNGs, and EXRs with error channels. The PNG pattern is given with a
  // ".." to show it is recorded resolved, as a client elsewhere must use it.
  CliResult png = farm.cli({"submit", kScene.string(), "--coordinator", farm.address(), "--detach", "-o",
                            (farm.dir() / "elsewhere" / ".." / "share" / "png" / "f_####.png").string(), "--tonemap",
                            "aces", "--exposure", "0.5"});
  ASSERT_EQ(png.code, 0) << png.output;
  EXPECT_NE(png.output.find("recorded with the job"), std::string::npos) << png.output;
  CliResult exr = farm.cli({"submit", kScene.string(), "--coordinator", farm.address(), "--detach", "-o",
                            (share / "exr" / "f_####.exr").string(), "--error-channels", "--target-rmse", "0.02"});
  ASSERT_EQ(exr.code, 0) << exr.output;
  const std::string png_job = job_id_from(png.output), exr_job = job_id_from(exr.output);
  ASSERT_TRUE(poll_until(std::chrono::seconds(120), [&] {
    std::string a, b;
    farm.tiles_done(png_job, &a);
    farm.tiles_done(exr_job, &b);
    return a == "done" && b == "done";
  })) << farm.server_logs();
  farm.restart_server();  // kill -9: the recorded outputs come back from the database

  CliResult st = farm.cli({"status", png_job, "--json", "--coordinator", farm.address()});
  ASSERT_EQ(st.code, 0) << st.output;
  const auto out = nlohmann::json::parse(st.output).at("output");
  EXPECT_EQ(out.at("pattern"), (share / "png" / "f_####.png").string());
  EXPECT_EQ(out.at("tonemap"), "aces");
  EXPECT_FLOAT_EQ(out.at("exposure_ev").get<float>(), 0.5f);
  CliResult human = farm.cli({"status", png_job, "--coordinator", farm.address()});
  EXPECT_NE(human.output.find("output: " + (share / "png" / "f_####.png").string()), std::string::npos)
      << human.output;

  // No -o: the recorded output, with its options.
  CliResult w1 = farm.cli({"watch", png_job, "--coordinator", farm.address()});
  ASSERT_EQ(w1.code, 0) << w1.output << farm.server_logs();
  EXPECT_NE(w1.output.find("recorded with the job"), std::string::npos) << w1.output;
  CliResult w2 = farm.cli({"watch", exr_job, "--coordinator", farm.address(), "-q"});
  ASSERT_EQ(w2.code, 0) << w2.output << farm.server_logs();
  for (int f = 0; f < 3; ++f) {
    const fs::path ref = farm.dir() / frame_name("ref", f, "png");
    ASSERT_EQ(farm.cli({"render", kScene.string(), "-o", ref.string(), "--frame", std::to_string(f), "-q",
                        "--tonemap", "aces", "--exposure", "0.5"})
                  .code,
              0);
    const fs::path got = share / "png" / frame_name("f", f, "png");
    ASSERT_TRUE(fs::exists(got)) << got;
    EXPECT_EQ(read_text(got), read_text(ref)) << got << " differs from tessera render's PNG";
    EXPECT_EQ(compare_exr(share / "exr" / frame_name("f", f, "exr"),
                          reference_frame(kScene, f, {"--error-channels", "--target-rmse", "0.02"})),
              "")
        << "frame " << f;
  }
  // Error channels were written as recorded: the EXR has the error layer.
  EXPECT_NE(read_text(share / "exr" / frame_name("f", 0, "exr")).find("error.Y"), std::string::npos);
}

// A job without a recorded output says so, and watch without -o only shows progress, as before.
TEST(FarmRecordedOutput, AJobSubmittedWithoutAnOutputHasNone) {
  Farm farm;
  farm.start_server();
  CliResult r = farm.cli({"submit", kScene.string(), "--coordinator", farm.address(), "--detach"});
  ASSERT_EQ(r.code, 0) << r.output;
  CliResult st = farm.cli({"status", job_id_from(r.output), "--json", "--coordinator", farm.address()});
  ASSERT_EQ(st.code, 0) << st.output;
  EXPECT_TRUE(nlohmann::json::parse(st.output).at("output").is_null()) << st.output;
}

}  // namespace
}  // namespace tessera::farmtest
