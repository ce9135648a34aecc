// SPDX-License-Identifier: Apache-2.0
#include "farm/temp_file.h"

#include <gtest/gtest.h>
#include <sys/stat.h>

#include <fstream>
#include <iterator>
#include <set>
#include <stdexcept>
#include <vector>

namespace tessera::farm {
namespace {

namespace fs = std::filesystem;

class TempFileTest : public ::testing::Test {
 protected:
  void SetUp() override { dir_ = make_temp_dir(fs::temp_directory_path(), "tessera-temp-file-test"); }
  void TearDown() override { fs::remove_all(dir_); }
  fs::path dir_;
};

TEST_F(TempFileTest, EachCallMakesANewEmptyFileThatKeepsItsExtension) {
  std::set<fs::path> seen;
  for (int i = 0; i < 50; ++i) {
    const fs::path p = make_temp_file(dir_, "frame_0001.tmp", ".exr");
    EXPECT_TRUE(seen.insert(p).second) << p;
    EXPECT_EQ(p.parent_path(), dir_);
    EXPECT_EQ(p.extension(), ".exr");
    EXPECT_EQ(p.filename().string().rfind("frame_0001.tmp.", 0), 0u) << p;
    EXPECT_TRUE(fs::is_regular_file(p));
    EXPECT_EQ(fs::file_size(p), 0u);
  }
}

TEST_F(TempFileTest, OwnerOnlyUnlessAskedReadable) {
  struct stat st {};
  ASSERT_EQ(stat(make_temp_file(dir_, "a").c_str(), &st), 0);
  EXPECT_EQ(st.st_mode & 0777, 0600u);
  ASSERT_EQ(stat(make_temp_file(dir_, "b", ".png", TempAccess::kReadable).c_str(), &st), 0);
  EXPECT_EQ(st.st_mode & 0777, 0644u);
}

TEST_F(TempFileTest, FoldersAreNewAndAMissingParentIsNamed) {
  const fs::path a = make_temp_dir(dir_, "bundle.tmp"), b = make_temp_dir(dir_, "bundle.tmp");
  EXPECT_NE(a, b);
  EXPECT_TRUE(fs::is_directory(a) && fs::is_empty(a));
  try {
    make_temp_file(dir_ / "missing", "x");
    FAIL() << "no error for a missing folder";
  } catch (const fs::filesystem_error& e) {
    EXPECT_NE(std::string(e.what()).find("missing"), std::string::npos) << e.what();
  }
}

// write_in_place: the writer sees a temporary name with the final extension; afterwards only the
// final file is there, readable; a writer that throws leaves no file at all, and an earlier file
// under the name is kept untouched.
std::string read_all(const fs::path& p) {
  std::ifstream in(p);
  return std::string(std::istreambuf_iterator<char>(in), {});
}

TEST_F(TempFileTest, WriteInPlaceLeavesTheWholeFileOrNothing) {
  const fs::path out = dir_ / "frame_0003.png";
  std::string seen;
  write_in_place(out, [&](const std::string& tmp) {
    seen = tmp;
    std::ofstream(tmp) << "new";
  });
  EXPECT_EQ(fs::path(seen).extension(), ".png");
  EXPECT_NE(fs::path(seen).filename(), out.filename());
  EXPECT_EQ(read_all(out), "new");
  struct stat st {};
  ASSERT_EQ(stat(out.c_str(), &st), 0);
  EXPECT_EQ(st.st_mode & 0777, 0644u);
  EXPECT_THROW(write_in_place(out,
                              [&](const std::string& tmp) {
                                std::ofstream(tmp) << "half";
                                throw std::runtime_error("disk full");
                              }),
               std::runtime_error);
  EXPECT_EQ(read_all(out), "new");
  std::vector<std::string> left;
  for (const auto& e : fs::directory_iterator(dir_)) left.push_back(e.path().filename().string());
  EXPECT_EQ(left, std::vector<std::string>{"frame_0003.png"});
}

}  // namespace
}  // namespace tessera::farm
