// SPDX-License-Identifier: Apache-2.0
// A throwaway PKI for the TLS tests (farm security, the ray service): made per test run with
// openssl in a temporary directory.
#pragma once

#include <filesystem>

namespace tessera::farmtest {

namespace fs = std::filesystem;

// A CA, a server certificate for 127.0.0.1/localhost and two client certificates (CN client-1,
// client-2) signed by it, and a second, unrelated CA. EC P-256 keys: quick to make.
struct Pki {
  fs::path dir;
  fs::path ca, server_cert, server_key, client_cert, client_key, other_ca;
  fs::path client2_cert, client2_key;  // a second client identity (CN client-2)
};

// Makes one under dir/pki; throws std::runtime_error naming the openssl command that failed.
Pki make_pki(const fs::path& dir);

}  // namespace tessera::farmtest
