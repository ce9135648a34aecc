// SPDX-License-Identifier: Apache-2.0
#include "peer_text.h"

#include <gtest/gtest.h>

namespace tessera::farm {
namespace {

TEST(PeerText, ShortTextIsKeptAndControlCharactersBecomeSpaces) {
  EXPECT_EQ(peer_text("cannot load\nthe\tscene"), "cannot load the scene");
  EXPECT_EQ(peer_text(""), "");
}

TEST(PeerText, LongTextIsCutAndSaysItsSize) {
  const std::string big(20 << 20, 'x');
  const std::string t = peer_text(big, 100);
  EXPECT_EQ(t, std::string(100, 'x') + "... (20971520 bytes)");
}

TEST(PeerText, NeverCutsAUtf8CharacterInHalf) {
  // "é" is two bytes (C3 A9): a cut after one of them keeps neither.
  const std::string s = "ab\xC3\xA9" "cd";
  EXPECT_EQ(peer_text(s, 3), "ab... (6 bytes)");
  EXPECT_EQ(peer_text(s, 4), "ab\xC3\xA9... (6 bytes)");
}

TEST(PeerText, JobIdsOverTheBoundAreRefusedWithoutBeingEchoed) {
  EXPECT_TRUE(check_job_id("0123456789ab").ok());
  EXPECT_TRUE(check_job_id(std::string(kMaxJobIdBytes, 'a')).ok());
  const grpc::Status s = check_job_id(std::string(1 << 20, 'z'));
  EXPECT_EQ(s.error_code(), grpc::StatusCode::INVALID_ARGUMENT);
  EXPECT_EQ(s.error_message().find("zz"), std::string::npos);
  EXPECT_NE(s.error_message().find("job_id: 1048576 bytes, at most 64"), std::string::npos) << s.error_message();
}

}  // namespace
}  // namespace tessera::farm
