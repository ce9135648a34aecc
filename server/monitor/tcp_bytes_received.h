// SPDX-License-Identifier: Apache-2.0
// The kernel's count of the bytes a TCP socket has received (TCP_INFO's tcpi_bytes_received):
// what the peer sent, whether the program has read it yet or not. In a file of its own because it
// needs <linux/tcp.h>, which clashes with the <netinet/tcp.h> that cpp-httplib includes.
#pragma once

#include <cstdint>

namespace tessera::server {

// 0 when the descriptor is not a TCP socket (or the kernel does not say).
uint64_t tcp_bytes_received(int fd);

}  // namespace tessera::server
