// SPDX-License-Identifier: Apache-2.0
#include "farm/bundle_fetch.h"

#include <chrono>

namespace tessera::farm {

std::string fetch_bundle(tessera::v1::WorkerService::Stub& stub, const std::string& sha256) {
  grpc::ClientContext ctx;
  ctx.set_deadline(std::chrono::system_clock::now() + std::chrono::minutes(10));
  tessera::v1::FetchBundleRequest req;
  req.set_sha256(sha256);
  auto reader = stub.FetchBundle(&ctx, req);
  std::string bytes;
  tessera::v1::BundleChunk chunk;
  while (reader->Read(&chunk)) bytes += chunk.data();
  grpc::Status s = reader->Finish();
  if (!s.ok()) throw FetchError(s.error_code(), "cannot fetch bundle " + sha256 + ": " + s.error_message());
  return bytes;
}

}  // namespace tessera::farm
