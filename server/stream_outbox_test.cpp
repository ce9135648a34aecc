// SPDX-License-Identifier: Apache-2.0
// The outbox's batching of shared payloads, driven by a reactor stand-in that records each write
// and completes it when the test says: runs of payloads queued back to back go into one message
// within the count and byte bounds, in order, never across another queued message.
#include "stream_outbox.h"

#include <gtest/gtest.h>

#include <string>
#include <vector>

#include "tessera/v1/client_service.pb.h"

namespace tessera::server {
namespace {

using Event = tessera::v1::WatchJobEvent;

struct RecordingReactor {
  std::vector<Event> written;
  bool finished = false;
  void StartWrite(const Event* m) { written.push_back(*m); }
  void Finish(const grpc::Status&) { finished = true; }
};

// What a write held: "f<frame>" for a frame_done, else the payloads of its tiles joined by ','.
std::string describe(const Event& e) {
  if (e.event_case() == Event::kFrameDone) return "f" + std::to_string(e.frame_done());
  std::string out;
  for (const std::string& t : e.tiles().tiles()) out += (out.empty() ? "" : ",") + t;
  return out;
}

std::shared_ptr<const std::string> payload(std::string s) { return std::make_shared<const std::string>(std::move(s)); }

TEST(StreamOutbox, QueuedPayloadsGoOutTogetherWithinTheBoundsAndInOrder) {
  RecordingReactor r;
  Outbox<RecordingReactor, Event> box(&r);
  size_t built = 0;
  box.set_batching(
      [&](Event* ev, const std::shared_ptr<const std::string>* p, size_t n) {
        ++built;
        for (size_t i = 0; i < n; ++i) ev->mutable_tiles()->add_tiles(*p[i]);
      },
      3, 10);
  box.push_shared(payload("a"));
  box.pump();  // written alone: nothing else was queued
  for (const char* p : {"b", "c", "d", "e"}) box.push_shared(payload(p));
  Event done;
  done.set_frame_done(7);
  box.push(done);
  box.push_shared(payload("0123456789"));  // a whole message's worth of bytes
  box.push_shared(payload("x"));
  box.push_shared(payload("y"));
  EXPECT_EQ(box.queued(), 8u);
  for (int i = 0; i < 10 && !r.finished; ++i) box.on_write_done(true);
  std::vector<std::string> got;
  for (const Event& e : r.written) got.push_back(describe(e));
  // At most 3 a message; the frame_done is never overtaken; past the first payload, no more than
  // 10 bytes a message.
  EXPECT_EQ(got, (std::vector<std::string>{"a", "b,c,d", "e", "f7", "0123456789", "x,y"}));
  EXPECT_EQ(built, 5u);
  EXPECT_EQ(box.queued(), 0u);
}

}  // namespace
}  // namespace tessera::server
