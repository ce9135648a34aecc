// SPDX-License-Identifier: Apache-2.0
// Ctrl-C and SIGTERM in the CLI. A job on the farm belongs to the farm, not to the client that
// submitted it: interrupting an attached `tessera submit` or `tessera watch` leaves the job
// rendering (as a client that dies or loses its network does) and says how to come back to it or
// stop it. Whatever the command, an interrupt never leaves half a file under an output's name: a
// file being written is finished first.
//
// Why a waiting thread and not a signal handler: the notice must follow the command's own output
// (stdout flushed, which a handler may not do), and waiting for a file to be finished needs a lock.
#pragma once

#include <mutex>
#include <string>

namespace tessera::cli {

// Blocks SIGINT and SIGTERM and starts the thread that takes them. Call first thing in main,
// before any thread exists (gRPC starts threads of its own with the first channel): a thread
// that does not block them could be handed the signal instead. On a signal the thread waits for
// any OutputWrite to end, prints the notice set by say_on_interrupt() (if any) on stderr, and
// ends the process by the signal's default action (exit status 128 + signal in a shell). A second
// signal ends it at once, without waiting.
void take_interrupts();

// A word a POSIX shell reads back as `s`: as is when that is safe, else in single quotes.
std::string shell_word(const std::string& s);

// What an interrupted watch of `job_id` says: the job keeps rendering, and the two commands that
// get its other frames (to `output`, if the watch wrote frames) or cancel it. The commands name the
// coordinator unless $TESSERA_COORDINATOR already names the same one.
std::string interrupt_notice(const std::string& job_id, const std::string& coordinator, const std::string& output);

// Sets what an interrupt prints before the process ends (one or more lines, no trailing newline).
void say_on_interrupt(std::string notice);

// While one exists, an interrupt waits: the file it guards is written whole (or not at all) and
// in place before the process ends.
class OutputWrite {
 public:
  OutputWrite();
  ~OutputWrite();
  OutputWrite(const OutputWrite&) = delete;
  OutputWrite& operator=(const OutputWrite&) = delete;

 private:
  std::unique_lock<std::mutex> lock_;
};

}  // namespace tessera::cli
