// SPDX-License-Identifier: Apache-2.0
#include "test_pki.h"

#include <cstdlib>
#include <fstream>
#include <stdexcept>
#include <string>

namespace tessera::farmtest {

namespace {

void sh(const std::string& cmd) {
  if (std::system(cmd.c_str()) != 0) throw std::runtime_error("failed: " + cmd);
}

}  // namespace

Pki make_pki(const fs::path& dir) {
  Pki p;
  p.dir = dir / "pki";
  fs::create_directories(p.dir);
  const std::string d = p.dir.string();
  const std::string key = "-newkey ec -pkeyopt ec_paramgen_curve:prime256v1 -nodes";
  std::ofstream(p.dir / "server.ext") << "subjectAltName=IP:127.0.0.1,DNS:localhost\n";
  std::ofstream(p.dir / "client.ext") << "extendedKeyUsage=clientAuth\n";
  const std::string q = " 2>>" + d + "/openssl.log";
  sh("cd " + d + " && openssl req -x509 " + key + " -keyout ca.key -out ca.pem -days 2 -subj '/CN=Tessera Test CA'" + q);
  sh("cd " + d + " && openssl req -x509 " + key + " -keyout other.key -out other-ca.pem -days 2 -subj '/CN=Other CA'" + q);
  for (const std::string who : {"server", "client", "client2"}) {
    const std::string cn = who == "server" ? "localhost" : who == "client" ? "client-1" : "client-2";
    if (who == "client2") fs::copy_file(p.dir / "client.ext", p.dir / "client2.ext");
    sh("cd " + d + " && openssl req " + key + " -keyout " + who + ".key -out " + who + ".csr -subj '/CN=" + cn + "'" + q);
    sh("cd " + d + " && openssl x509 -req -in " + who + ".csr -CA ca.pem -CAkey ca.key -CAcreateserial -days 2 -out " +
       who + ".pem -extfile " + who + ".ext" + q);
  }
  p.ca = p.dir / "ca.pem";
  p.other_ca = p.dir / "other-ca.pem";
  p.server_cert = p.dir / "server.pem";
  p.server_key = p.dir / "server.key";
  p.client_cert = p.dir / "client.pem";
  p.client_key = p.dir / "client.key";
  p.client2_cert = p.dir / "client2.pem";
  p.client2_key = p.dir / "client2.key";
  return p;
}

}  // namespace tessera::farmtest
