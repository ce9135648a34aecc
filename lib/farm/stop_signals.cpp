// SPDX-License-Identifier: Apache-2.0
#include "farm/stop_signals.h"

#include <pthread.h>

namespace tessera::farm {

sigset_t stop_signal_set() {
  sigset_t sigs;
  sigemptyset(&sigs);
  sigaddset(&sigs, SIGINT);
  sigaddset(&sigs, SIGTERM);
  return sigs;
}

int wait_for_signal(const sigset_t& sigs) {
  int sig = 0;
  sigwait(&sigs, &sig);  // fails only for a set with an invalid signal (glibc waits through EINTR)
  return sig;
}

sigset_t block_stop_signals() {
  ::signal(SIGPIPE, SIG_IGN);
  const sigset_t sigs = stop_signal_set();
  pthread_sigmask(SIG_BLOCK, &sigs, nullptr);
  return sigs;
}

}  // namespace tessera::farm
