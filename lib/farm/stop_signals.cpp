#include "farm/stop_signals.h"

#include <pthread.h>

namespace tessera::farm {

sigset_t block_stop_signals() {
  ::signal(SIGPIPE, SIG_IGN);
  sigset_t sigs;
  sigemptyset(&sigs);
  sigaddset(&sigs, SIGINT);
  sigaddset(&sigs, SIGTERM);
  pthread_sigmask(SIG_BLOCK, &sigs, nullptr);
  return sigs;
}

}  // namespace tessera::farm
