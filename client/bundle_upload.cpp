// SPDX-License-Identifier: Apache-2.0
#include "bundle_upload.h"

#include "command_error.h"

namespace tessera::cli {

bool upload_bundle_if_missing(FarmClient& client, const farm::BuiltBundle& b) {
  tessera::v1::HasBundleRequest hreq;
  hreq.set_sha256(b.sha256);
  tessera::v1::HasBundleResponse hresp;
  auto ctx = client.context();
  grpc::Status s = client.stub().HasBundle(ctx.get(), hreq, &hresp);
  if (!s.ok()) throw CommandError{kExitFailure, client.describe(s, "checking for the scene bundle")};
  if (hresp.present()) return false;
  // A minute plus a second per MiB, as `tessera submit` allows.
  auto uctx = FarmClient::context(std::chrono::seconds(60 + int64_t(b.bytes.size() >> 20)));
  tessera::v1::UploadBundleResponse uresp;
  auto writer = client.stub().UploadBundle(uctx.get(), &uresp);
  constexpr size_t kChunk = size_t(1) << 20;
  for (size_t off = 0; off == 0 || off < b.bytes.size(); off += kChunk) {
    tessera::v1::BundleChunk c;
    if (off == 0) c.set_sha256(b.sha256);
    c.set_data(b.bytes.substr(off, kChunk));
    if (!writer->Write(c)) break;  // the coordinator refused: Finish() says why
  }
  writer->WritesDone();
  s = writer->Finish();
  if (!s.ok()) throw CommandError{kExitFailure, client.describe(s, "uploading the scene bundle")};
  return true;
}

}  // namespace tessera::cli
