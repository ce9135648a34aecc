// SPDX-License-Identifier: Apache-2.0
#include "interrupt.h"

#include <gtest/gtest.h>
#include <signal.h>
#include <unistd.h>

#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <thread>

namespace tessera::cli {
namespace {

using namespace std::chrono_literals;

// Each death test runs its statement in a child process of its own: the interrupt thread, the
// blocked signals and the signal itself stay there.
class InterruptDeath : public ::testing::Test {
 protected:
  void SetUp() override { GTEST_FLAG_SET(death_test_style, "threadsafe"); }
};

[[noreturn]] void wait_to_be_ended(std::chrono::milliseconds most) {
  std::this_thread::sleep_for(most);
  std::_Exit(0);  // the signal did not end the process: the test sees exit 0, not the signal
}

TEST_F(InterruptDeath, ASignalEndsTheProcessByItselfAfterTheNotice) {
  EXPECT_EXIT(
      {
        take_interrupts();
        say_on_interrupt("interrupted: the notice");
        ::kill(::getpid(), SIGINT);
        wait_to_be_ended(10s);
      },
      ::testing::KilledBySignal(SIGINT), "interrupted: the notice");
  EXPECT_EXIT(
      {
        take_interrupts();
        ::kill(::getpid(), SIGTERM);
        wait_to_be_ended(10s);
      },
      ::testing::KilledBySignal(SIGTERM), "");
}

TEST_F(InterruptDeath, AFileBeingWrittenIsFinishedFirst) {
  EXPECT_EXIT(
      {
        take_interrupts();
        say_on_interrupt("the notice");
        {
          const OutputWrite whole;
          ::kill(::getpid(), SIGINT);
          std::this_thread::sleep_for(300ms);  // the signal is taken meanwhile, and waits
          std::fprintf(stderr, "the write ended\n");
        }
        wait_to_be_ended(10s);
      },
      ::testing::KilledBySignal(SIGINT), "the write ended.*the notice");
}

TEST_F(InterruptDeath, ASecondSignalDoesNotWaitForAWriteThatHangs) {
  EXPECT_EXIT(
      {
        take_interrupts();
        const OutputWrite stuck;
        ::kill(::getpid(), SIGINT);
        std::this_thread::sleep_for(200ms);
        ::kill(::getpid(), SIGTERM);
        wait_to_be_ended(10s);
      },
      ::testing::KilledBySignal(SIGTERM), "");
}

TEST(Interrupt, ShellWordsReadBackAsTheyWere) {
  EXPECT_EQ(shell_word("out/frame_####.exr"), "out/frame_####.exr");
  EXPECT_EQ(shell_word("127.0.0.1:7878"), "127.0.0.1:7878");
  EXPECT_EQ(shell_word("my renders/f_##.exr"), "'my renders/f_##.exr'");
  EXPECT_EQ(shell_word("it's.exr"), "'it'\\''s.exr'");
  EXPECT_EQ(shell_word("#f.exr"), "'#f.exr'");  // a word that starts with # is a comment
  EXPECT_EQ(shell_word("a$b"), "'a$b'");
  EXPECT_EQ(shell_word(""), "''");
}

TEST(Interrupt, TheNoticeSaysTheJobGoesOnAndHowToComeBackOrStopIt) {
  ::unsetenv("TESSERA_COORDINATOR");
  const std::string n = interrupt_notice("0a1b2c3d4e5f", "farm-head:7878", "out/shot_####.exr");
  EXPECT_NE(n.find("job 0a1b2c3d4e5f keeps rendering on the farm; the frames written so far stay"),
            std::string::npos) << n;
  EXPECT_NE(n.find("tessera watch 0a1b2c3d4e5f --coordinator farm-head:7878 -o out/shot_####.exr"), std::string::npos)
      << n;
  EXPECT_NE(n.find("tessera cancel 0a1b2c3d4e5f --coordinator farm-head:7878 "), std::string::npos) << n;

  // Without -o the watch only showed progress: coming back means watching again.
  ::setenv("TESSERA_COORDINATOR", "farm-head:7878", 1);
  const std::string p = interrupt_notice("0a1b2c3d4e5f", "farm-head:7878", "");
  EXPECT_EQ(p.find("--coordinator"), std::string::npos) << "the environment already names it\n" << p;
  EXPECT_EQ(p.find("frames written"), std::string::npos) << p;
  EXPECT_NE(p.find("tessera watch 0a1b2c3d4e5f  "), std::string::npos) << p;
  EXPECT_NE(p.find("re-attaches"), std::string::npos) << p;
  ::unsetenv("TESSERA_COORDINATOR");
}

}  // namespace
}  // namespace tessera::cli
