// SPDX-License-Identifier: Apache-2.0
#include "interrupt.h"

#include <signal.h>

#include <algorithm>
#include <cctype>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <thread>

#include "farm/stop_signals.h"

namespace tessera::cli {

namespace {

// These outlive static destruction on purpose (never deleted): the interrupt thread may take a
// signal while the process is already exiting normally.

// Held while an output file is written; the interrupt thread takes it and never gives it back,
// so nothing new starts being written once the process is ending.
std::mutex& write_mutex() {
  static auto* m = new std::mutex;
  return *m;
}

std::mutex& notice_mutex() {
  static auto* m = new std::mutex;
  return *m;
}

std::string& notice() {
  static auto* s = new std::string;
  return *s;
}

// The signal's own default action: a shell or a script sees the process ended by it.
[[noreturn]] void die_by(int sig) {
  ::signal(sig, SIG_DFL);
  sigset_t one;
  sigemptyset(&one);
  sigaddset(&one, sig);
  pthread_sigmask(SIG_UNBLOCK, &one, nullptr);
  ::raise(sig);
  std::_Exit(128 + sig);  // not reached: the default action of SIGINT and SIGTERM ends the process
}

[[noreturn]] void end_by(int sig, sigset_t sigs) {
  // A second interrupt ends the process at once: a write that does not finish (a full pipe, a
  // stalled network disk) must not make the client impossible to stop.
  std::thread([sigs] { die_by(farm::wait_for_signal(sigs)); }).detach();
  write_mutex().lock();  // the file being written is finished first
  {
    std::lock_guard lock(notice_mutex());
    std::fflush(stdout);
    if (!notice().empty()) std::fprintf(stderr, "\n%s\n", notice().c_str());
    std::fflush(stderr);
  }
  die_by(sig);
}

}  // namespace

void take_interrupts() {
  // Not farm::block_stop_signals(): that also ignores SIGPIPE, and `tessera status | head` should
  // end quietly by SIGPIPE, not report a failed write.
  const sigset_t sigs = farm::stop_signal_set();
  pthread_sigmask(SIG_BLOCK, &sigs, nullptr);
  std::thread([sigs] { end_by(farm::wait_for_signal(sigs), sigs); }).detach();
}

std::string shell_word(const std::string& s) {
  const bool plain = !s.empty() && std::all_of(s.begin(), s.end(), [](unsigned char c) {
    return std::isalnum(c) || (c != 0 && std::strchr("_-./#%+=,:@", c));
  }) && s[0] != '#';
  if (plain) return s;
  std::string q = "'";
  for (char c : s) q += c == '\'' ? std::string("'\\''") : std::string(1, c);
  return q + "'";
}

std::string interrupt_notice(const std::string& job_id, const std::string& coordinator, const std::string& output) {
  // The commands name the coordinator unless the environment already does.
  const char* env = std::getenv("TESSERA_COORDINATOR");
  const std::string at = env && coordinator == env ? "" : " --coordinator " + shell_word(coordinator);
  std::string watch = "tessera watch " + job_id + at;
  if (!output.empty()) watch += " -o " + shell_word(output);
  const std::string cancel = "tessera cancel " + job_id + at;
  const size_t width = std::max(watch.size(), cancel.size()) + 2;
  return "interrupted: job " + job_id + " keeps rendering on the farm" +
         (output.empty() ? "" : "; the frames written so far stay") + ".\n  " + watch +
         std::string(width - watch.size(), ' ') + (output.empty() ? "re-attaches" : "writes the others") + "\n  " +
         cancel + std::string(width - cancel.size(), ' ') + "stops it";
}

void say_on_interrupt(std::string text) {
  std::lock_guard lock(notice_mutex());
  notice() = std::move(text);
}

OutputWrite::OutputWrite() : lock_(write_mutex()) {}

OutputWrite::~OutputWrite() = default;

}  // namespace tessera::cli
