// SPDX-License-Identifier: Apache-2.0
// Keeps a gRPC server (the coordinator, the ray server) accepting connections when it runs out
// of descriptors.
//
// gRPC 1.51 (Debian bookworm) drops its listener for good the first time accept4() fails with
// EMFILE or ENFILE: its accept loop (tcp_server_posix.cc) ends on any error but EINTR, EAGAIN
// and ECONNABORTED, and the port is never served again. Anyone who can reach the port can cause
// that with a few hundred idle connections under a hard descriptor limit. A later gRPC pauses and
// retries; this one cannot be configured to.
//
// So these programs define accept4() themselves (accept_guard.cpp; the library
// tessera_accept_guard exports it from the executable that links it). The dynamic linker binds
// libgrpc's call to the executable's definition, which makes the system call and, when the
// process is out of descriptors, closes the connections waiting on that listener with the help
// of one spare descriptor kept for the purpose (the remedy libev and nginx use: close the spare,
// accept, close, reopen it), then reports EAGAIN, on which gRPC waits for the next connection
// as it does on an empty queue. Connections are shed only while descriptors are exhausted;
// serving resumes by itself once they come back (the handshake timeout returns idle ones).
#pragma once

namespace tessera::farm {

// Opens the spare descriptor. Call once at start, before the gRPC server listens; until then
// accept4() only turns EMFILE/ENFILE into EAGAIN.
void install_accept_guard();

}  // namespace tessera::farm
