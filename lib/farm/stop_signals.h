// SPDX-License-Identifier: Apache-2.0
// How the farm's programs take SIGINT and SIGTERM: one thread waits for them with sigwait and
// stops the program cleanly (the coordinator commits what is queued, a worker returns its
// unstarted tiles); no thread ever takes them by the default action, which would end the process
// with nothing committed.
#pragma once

#include <signal.h>

namespace tessera::farm {

// SIGINT and SIGTERM: the signals that stop a farm program (the CLI takes the same two).
sigset_t stop_signal_set();

// Waits for one of `sigs` (blocked in every thread) and returns it.
int wait_for_signal(const sigset_t& sigs);

// Ignores SIGPIPE and blocks SIGINT and SIGTERM in the calling thread; returns the blocked set for
// sigwait. Call it first thing in main, before anything that may start a thread: a thread keeps
// the mask it was started with, and gRPC starts its executor and timer threads as soon as the
// first credentials object is made. The kernel gives a process-wide signal to any thread that
// does not block it, so one such thread is enough to turn a clean stop into a kill.
//
// SIGPIPE: a write to a pipe or socket whose reader went away must cost that write, not the
// process (spdlog writing to `program | tee` or a log shipper that restarted; OpenSSL writes
// without MSG_NOSIGNAL; gRPC asks for it).
sigset_t block_stop_signals();

}  // namespace tessera::farm
