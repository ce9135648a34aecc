// SPDX-License-Identifier: Apache-2.0
// The coordinator's HTTP side, end to end: a real coordinator with --http-listen,
// real workers and the real CLI on 127.0.0.1; the monitor's API under tokens, owners and TLS;
// a real Prometheus server scraping /metrics; and the monitor in headless Chromium (jobs, workers,
// a ray server).
#include <gtest/gtest.h>
#include <httplib.h>
#include <netinet/in.h>
#include <openssl/ssl.h>
#include <poll.h>
#include <sys/socket.h>
#include <unistd.h>

#include <nlohmann/json.hpp>
#include <algorithm>
#include <atomic>
#include <csignal>
#include <fstream>
#include <regex>
#include <thread>

#include "color/png_io.h"
#include "../rays/rays_harness.h"
#include "farm_harness.h"

namespace tessera::farmtest {
namespace {

using namespace std::chrono_literals;
using nlohmann::json;

const fs::path kScene = source("tests/farm/whitted_orbit.json");  // 96x64, 3 frames
constexpr int kTilesPerFrame = 24;                                 // at --tile 16

void write(const fs::path& p, const std::string& text) {
  std::ofstream out(p);
  out << text;
}

// The port of the coordinator's HTTP listener, from its "monitor on" line.
int http_port(Farm& farm) {
  const std::regex re("monitor on https?://127\\.0\\.0\\.1:([0-9]+)/");
  for (int i = 0; i < 200; ++i) {
    std::smatch m;
    const std::string log = farm.server().log();
    if (std::regex_search(log, m, re)) return std::stoi(m[1]);
    std::this_thread::sleep_for(25ms);
  }
  ADD_FAILURE() << "no 'monitor on' line:\n" << farm.server().log();
  return 0;
}

// A real Prometheus on 127.0.0.1:prom_port scraping the coordinator's /metrics on `port` every second.
std::unique_ptr<Process> start_prometheus(Farm& farm, int port, int prom_port) {
  write(farm.dir() / "prometheus.yml", "global:\n  scrape_interval: 1s\n  scrape_timeout: 1s\n"
                                       "scrape_configs:\n  - job_name: tessera\n    static_configs:\n"
                                       "      - targets: ['127.0.0.1:" + std::to_string(port) + "']\n");
  return std::make_unique<Process>(
      std::vector<std::string>{"/usr/bin/prometheus", "--config.file", (farm.dir() / "prometheus.yml").string(),
                               "--storage.tsdb.path", (farm.dir() / "prometheus-data").string(),
                               "--web.listen-address", "127.0.0.1:" + std::to_string(prom_port)},
      farm.dir() / "prometheus.log");
}

httplib::Headers bearer(const std::string& token) { return {{"Authorization", "Bearer " + token}}; }

// Named client tokens: alice and bob each own what they submit (job_access.h).
TEST(MonitorHttp, EveryCallChecksTheTokenAndActionsNeedTheJobsOwner) {
  Farm farm;
  write(farm.dir() / "tokens", "alice:alice-secret-1\nbob:bob-secret-2\n");
  farm.start_server({"--http-listen", "127.0.0.1:0", "--client-tokens", (farm.dir() / "tokens").string()});
  httplib::Client http("127.0.0.1", http_port(farm));
  write(farm.dir() / "alice.token", "alice-secret-1\n");
  // No worker: the job stays queued, so its priority can change and it can be cancelled.
  CliResult sub = farm.cli({"submit", kScene.string(), "--coordinator", farm.address(), "--detach", "--tile", "16",
                            "--token-file", (farm.dir() / "alice.token").string(), "--name", "alices-job"});
  ASSERT_EQ(sub.code, 0) << sub.output;
  const std::string job = job_id_from(sub.output);

  // The page itself holds no farm data: it loads, and asks for a token.
  auto page = http.Get("/");
  ASSERT_TRUE(page);
  EXPECT_EQ(page->status, 200);
  EXPECT_NE(page->body.find("id=\"login\""), std::string::npos);
  // Everything else needs a valid token.
  for (const std::string& path : std::vector<std::string>{"/api/farm", "/api/whoami", "/metrics", "/api/jobs/" + job,
                                 "/api/jobs/" + job + "/preview.png"}) {
    auto none = http.Get(path);
    ASSERT_TRUE(none) << path;
    EXPECT_EQ(none->status, 401) << path << ": " << none->body;
    auto wrong = http.Get(path, bearer("alice-secret-X"));
    ASSERT_TRUE(wrong) << path;
    EXPECT_EQ(wrong->status, 401) << path << ": " << wrong->body;
  }
  auto farm_json = http.Get("/api/farm", bearer("bob-secret-2"));
  ASSERT_TRUE(farm_json);
  ASSERT_EQ(farm_json->status, 200) << farm_json->body;
  const json jobs = json::parse(farm_json->body).at("jobs");
  ASSERT_EQ(jobs.size(), 1u);
  EXPECT_EQ(jobs[0].at("id"), job);
  EXPECT_EQ(jobs[0].at("owner"), "token:alice");
  EXPECT_EQ(jobs[0].at("name"), "alices-job");
  EXPECT_EQ(jobs[0].at("state"), "queued");
  EXPECT_EQ(jobs[0].at("tiles_total"), 3 * kTilesPerFrame);

  // Bob may not watch, reprioritize or cancel alice's job; alice may.
  EXPECT_EQ(http.Get("/api/jobs/" + job, bearer("bob-secret-2"))->status, 403);
  auto denied = http.Post("/api/jobs/" + job + "/cancel", bearer("bob-secret-2"), "{}", "application/json");
  ASSERT_TRUE(denied);
  EXPECT_EQ(denied->status, 403) << denied->body;
  EXPECT_NE(denied->body.find("token:bob"), std::string::npos) << denied->body;
  // An action must come with a JSON body (a form posted by another site cannot send one).
  auto form = http.Post("/api/jobs/" + job + "/cancel", bearer("alice-secret-1"), "x=1",
                        "application/x-www-form-urlencoded");
  ASSERT_TRUE(form);
  EXPECT_EQ(form->status, 400) << form->body;
  auto bad = http.Post("/api/jobs/" + job + "/priority", bearer("alice-secret-1"), R"({"priority":"high"})",
                       "application/json");
  ASSERT_TRUE(bad);
  EXPECT_EQ(bad->status, 400);
  EXPECT_NE(bad->body.find("priority"), std::string::npos) << bad->body;
  auto prio = http.Post("/api/jobs/" + job + "/priority", bearer("alice-secret-1"), R"({"priority":7})",
                        "application/json");
  ASSERT_TRUE(prio);
  ASSERT_EQ(prio->status, 200) << prio->body;
  CliResult st = farm.cli({"status", job, "--json", "--coordinator", farm.address(), "--token-file",
                           (farm.dir() / "alice.token").string()});
  ASSERT_EQ(st.code, 0) << st.output;
  EXPECT_EQ(json::parse(st.output).at("priority"), 7);
  // The CLI's SetJobPriority has the same rule.
  write(farm.dir() / "bob.token", "bob-secret-2\n");
  CliResult bob = farm.cli({"priority", job, "1", "--coordinator", farm.address(), "--token-file",
                            (farm.dir() / "bob.token").string()});
  EXPECT_NE(bob.code, 0) << bob.output;
  CliResult alice = farm.cli({"priority", job, "3", "--coordinator", farm.address(), "--token-file",
                              (farm.dir() / "alice.token").string()});
  ASSERT_EQ(alice.code, 0) << alice.output;
  EXPECT_NE(alice.output.find("priority 3"), std::string::npos) << alice.output;
  auto cancel = http.Post("/api/jobs/" + job + "/cancel", bearer("alice-secret-1"), "{}", "application/json");
  ASSERT_TRUE(cancel);
  ASSERT_EQ(cancel->status, 200) << cancel->body;
  CliResult gone = farm.cli({"status", job, "--json", "--coordinator", farm.address(), "--token-file",
                            (farm.dir() / "alice.token").string()});
  ASSERT_EQ(gone.code, 0) << gone.output;
  EXPECT_EQ(json::parse(gone.output).at("state"), "cancelled");
  // The priority of an ended job is refused, by name.
  auto late = http.Post("/api/jobs/" + job + "/priority", bearer("alice-secret-1"), R"({"priority":1})",
                        "application/json");
  ASSERT_TRUE(late);
  EXPECT_EQ(late->status, 409) << late->body;
  // The priority survives a restart (it is stored with the job).
  CliResult other = farm.cli({"submit", kScene.string(), "--coordinator", farm.address(), "--detach", "--token-file",
                              (farm.dir() / "alice.token").string()});
  ASSERT_EQ(other.code, 0) << other.output;
  const std::string job2 = job_id_from(other.output);
  ASSERT_EQ(farm.cli({"priority", job2, "-4", "--coordinator", farm.address(), "--token-file",
                      (farm.dir() / "alice.token").string()}).code, 0);
  farm.restart_server();
  CliResult after = farm.cli({"status", job2, "--json", "--coordinator", farm.address(), "--token-file",
                              (farm.dir() / "alice.token").string()});
  ASSERT_EQ(after.code, 0) << after.output;
  EXPECT_EQ(json::parse(after.output).at("priority"), -4);
}

TEST(MonitorHttp, TlsServesHttpsWithTheCoordinatorsCertificate) {
  Farm farm;
  const fs::path d = farm.dir();
  ASSERT_EQ(std::system(("cd " + d.string() + " && openssl req -x509 -newkey ec -pkeyopt ec_paramgen_curve:prime256v1 "
                         "-nodes -keyout server.key -out server.pem -days 2 -subj /CN=localhost "
                         "-addext subjectAltName=IP:127.0.0.1 2>openssl.log").c_str()),
            0);
  farm.start_server({"--http-listen", "127.0.0.1:0", "--tls-cert", (d / "server.pem").string(), "--tls-key",
                     (d / "server.key").string()});
  const int port = http_port(farm);
  EXPECT_NE(farm.server().log().find("monitor on https://"), std::string::npos);
  httplib::SSLClient https("127.0.0.1", port);
  https.set_ca_cert_path((d / "server.pem").c_str());
  https.enable_server_certificate_verification(true);
  auto ok = https.Get("/api/farm");
  ASSERT_TRUE(ok) << httplib::to_string(ok.error());
  EXPECT_EQ(ok->status, 200);
  EXPECT_TRUE(json::parse(ok->body).contains("workers"));
  // Plain HTTP on the same port gets no answer.
  httplib::Client plain("127.0.0.1", port);
  plain.set_read_timeout(3, 0);
  auto no = plain.Get("/api/farm");
  EXPECT_TRUE(!no || no->status != 200);
}

// Clients that leave while the answer is being written, as a browser tab closed mid-load does:
// after the request they close (FIN: the server's next write meets a reset peer, EPIPE) or reset
// (RST, SO_LINGER 0), over plain HTTP and over TLS, without reading the answer. Each costs its own
// connection only: the coordinator runs on (SIGPIPE would end it), answers the next client, and
// the farm's gRPC side is unaffected. (cpp-httplib ignores SIGPIPE itself when its server is made,
// so this holds without server/main.cpp's guard too; that guard's own test is
// FarmFaults.ALogReaderThatGoesAwayEndsNeitherCoordinatorNorWorker.)
TEST(MonitorHttp, ClientsThatLeaveMidAnswerCostOnlyTheirConnection) {
  const auto leave = [](int port, SSL_CTX* tls, bool reset) {
    const std::vector<int> c = silent_connections(port, 1);
    if (c.size() != 1) return false;
    const std::string req = "GET / HTTP/1.1\r\nHost: 127.0.0.1\r\n\r\n";
    bool sent = false;
    if (tls) {
      SSL* ssl = SSL_new(tls);
      SSL_set_fd(ssl, c[0]);
      sent = SSL_connect(ssl) == 1 && SSL_write(ssl, req.data(), int(req.size())) == int(req.size());
      SSL_free(ssl);  // no close_notify: the peer just goes
    } else {
      sent = send(c[0], req.data(), req.size(), MSG_NOSIGNAL) == ssize_t(req.size());
    }
    if (reset) {
      const linger hard{1, 0};
      setsockopt(c[0], SOL_SOCKET, SO_LINGER, &hard, sizeof hard);
    }
    close(c[0]);
    return sent;
  };
  for (const bool use_tls : {false, true}) {
    SCOPED_TRACE(use_tls ? "https" : "http");
    Farm farm;
    const fs::path d = farm.dir();
    std::vector<std::string> args{"--http-listen", "127.0.0.1:0"};
    SSL_CTX* tls = nullptr;
    if (use_tls) {
      ASSERT_EQ(std::system(("cd " + d.string() + " && openssl req -x509 -newkey ec -pkeyopt "
                             "ec_paramgen_curve:prime256v1 -nodes -keyout server.key -out server.pem -days 2 "
                             "-subj /CN=localhost -addext subjectAltName=IP:127.0.0.1 2>openssl.log").c_str()),
                0);
      args.insert(args.end(), {"--tls-cert", (d / "server.pem").string(), "--tls-key", (d / "server.key").string()});
      tls = SSL_CTX_new(TLS_client_method());  // no verification: these clients only leave
    }
    farm.start_server(args);
    const int port = http_port(farm);
    int sent = 0;
    for (int i = 0; i < 60; ++i) sent += leave(port, tls, i % 2 == 1);
    EXPECT_EQ(sent, 60);
    std::this_thread::sleep_for(500ms);  // the answers meet the closed connections
    EXPECT_TRUE(farm.server().running()) << "the coordinator died:\n" << farm.server().log();
    std::unique_ptr<httplib::Client> http = std::make_unique<httplib::Client>(
        (use_tls ? "https://127.0.0.1:" : "http://127.0.0.1:") + std::to_string(port));
    http->enable_server_certificate_verification(false);
    auto r = http->Get("/api/farm");
    ASSERT_TRUE(r) << httplib::to_string(r.error());
    EXPECT_EQ(r->status, 200);
    std::vector<std::string> status{"status", "--coordinator", farm.address()};
    if (use_tls) status.insert(status.end(), {"--tls-ca", (d / "server.pem").string()});
    EXPECT_EQ(farm.cli(status).code, 0) << "the gRPC side";
    if (tls) SSL_CTX_free(tls);
  }
}

// The slow-client attack, reproduced: 40 connections send a request line, then one header byte a
// second. While they do, /metrics answers everyone else at once (before: it timed out, 8 s, and
// Prometheus would mark the farm down); and the server closes each of them once its request head
// has taken longer than the 10 s a request gets (http_connections.h), not at the client's pace.
TEST(MonitorHttp, SlowClientsDoNotStarveTheWebSide) {
  Farm farm;
  farm.start_server({"--http-listen", "127.0.0.1:0"});
  const int port = http_port(farm);
  constexpr int kSlow = 40;
  // Each sends its request line as soon as it is connected, as a slow client does (a connection
  // silent for 2 s is closed by the keep-alive wait, deadline or not).
  std::vector<int> slow;
  std::vector<std::chrono::steady_clock::time_point> connected;
  const std::string line = "GET /metrics HTTP/1.1\r\nHost: 127.0.0.1\r\n";
  for (int i = 0; i < kSlow; ++i) {
    const std::vector<int> one = silent_connections(port, 1);
    ASSERT_EQ(one.size(), 1u);
    slow.push_back(one[0]);
    connected.push_back(std::chrono::steady_clock::now());
    ASSERT_EQ(send(one[0], line.data(), line.size(), MSG_NOSIGNAL), ssize_t(line.size()));
  }
  std::atomic<bool> done{false};
  std::vector<double> closed_after(kSlow, -1);  // seconds from its connect, when the server closed it
  std::thread dribble([&] {
    while (!done) {
      for (int i = 0; i < kSlow; ++i) {
        if (closed_after[size_t(i)] >= 0) continue;
        char c;
        const ssize_t r = recv(slow[size_t(i)], &c, 1, MSG_DONTWAIT);
        if (r == 0 || (r < 0 && errno != EAGAIN && errno != EWOULDBLOCK) ||
            send(slow[size_t(i)], "X", 1, MSG_NOSIGNAL) != 1) {
          closed_after[size_t(i)] =
              std::chrono::duration<double>(std::chrono::steady_clock::now() - connected[size_t(i)]).count();
        }
      }
      std::this_thread::sleep_for(1s);
    }
  });
  std::this_thread::sleep_for(1s);  // every slow connection accepted and being read
  for (int k = 0; k < 3; ++k) {
    httplib::Client http("127.0.0.1", port);
    http.set_connection_timeout(3, 0);
    http.set_read_timeout(3, 0);
    auto r = http.Get("/metrics");
    ASSERT_TRUE(r) << "request " << k << ": " << httplib::to_string(r.error());
    EXPECT_EQ(r->status, 200);
    EXPECT_NE(r->body.find("tessera_"), std::string::npos);
  }
  // The slow ones are closed by the server after their 10 s, well before their client would stop.
  for (int i = 0; i < 250 && std::count(closed_after.begin(), closed_after.end(), -1.0) > 0; ++i) {
    std::this_thread::sleep_for(100ms);
  }
  done = true;
  dribble.join();
  for (int i = 0; i < kSlow; ++i) {
    EXPECT_GE(closed_after[size_t(i)], 9.0) << "connection " << i << " closed too early";
    EXPECT_LE(closed_after[size_t(i)], 18.0) << "connection " << i << " was not closed in time";
    close(slow[size_t(i)]);
  }
  EXPECT_NE(farm.server().log().find("HTTP: closed"), std::string::npos) << farm.server().log();
}

struct Answer {
  int status = 0;  // 0: no answer
  std::string text;
  int64_t body_sent = 0;
};

// Whether `text` holds a whole HTTP response (head, and as much body as its Content-Length says).
bool whole_response(const std::string& text) {
  const size_t head_end = text.find("\r\n\r\n");
  if (head_end == std::string::npos) return false;
  std::smatch m;
  const std::string head = text.substr(0, head_end);
  const size_t body = std::regex_search(head, m, std::regex("[Cc]ontent-[Ll]ength: *([0-9]+)")) ? std::stoul(m[1]) : 0;
  return text.size() >= head_end + 4 + body;
}

// Sends `head` (a request line and headers), then up to `body_bytes` of `filler` over and over
// (zeros by default; the test never holds the body), until the server answers or ends the
// connection; what the server said. A server that reads the whole body first answers only once it
// was all sent.
Answer post_streaming(int port, const std::string& head, int64_t body_bytes,
                      const std::string& filler = std::string(256 << 10, '\0')) {
  Answer a;
  const std::vector<int> c = silent_connections(port, 1);
  if (c.size() != 1) return a;
  const int fd = c[0];
  const std::string& zeros = filler;
  bool open = send(fd, head.data(), head.size(), MSG_NOSIGNAL) == ssize_t(head.size());
  while (open && !whole_response(a.text)) {
    pollfd p{fd, short(POLLIN | (a.body_sent < body_bytes ? POLLOUT : 0)), 0};
    if (poll(&p, 1, 60000) <= 0) break;  // neither reads nor answers for a minute: give up
    if (p.revents & (POLLIN | POLLHUP | POLLERR)) {
      char buf[4096];
      const ssize_t n = recv(fd, buf, sizeof buf, 0);
      open = n > 0;
      if (open) a.text.append(buf, size_t(n));
      continue;
    }
    const size_t want = size_t(std::min<int64_t>(int64_t(zeros.size()), body_bytes - a.body_sent));
    const ssize_t n = send(fd, zeros.data(), want, MSG_NOSIGNAL | MSG_DONTWAIT);
    if (n > 0) a.body_sent += n;
    if (n < 0 && errno != EAGAIN && errno != EWOULDBLOCK) {
      // Closed on us mid-body: the answer, if any, is already here.
      char buf[4096];
      for (ssize_t r; (r = recv(fd, buf, sizeof buf, MSG_DONTWAIT)) > 0;) a.text.append(buf, size_t(r));
      open = false;
    }
  }
  close(fd);
  if (a.text.rfind("HTTP/1.1 ", 0) == 0) a.status = std::stoi(a.text.substr(9, 3));
  return a;
}

// Request bodies cost the coordinator nothing before the token is checked, on every route (an
// unknown one too), and nothing beyond a small bound after: four unauthenticated 300 MiB POSTs
// used to be read whole into memory before their 401 (1,095 MiB peak for four of 200 MiB; one of
// 1.5 GiB ended the coordinator with std::bad_alloc under an address-space limit). Now each is
// answered after its head, the connection closed, and an authenticated body over the limit is
// refused naming it; a body of unknown length (chunked, or none declared) is refused as well.
TEST(MonitorHttp, BodiesAreRefusedUnreadWithoutATokenAndBoundedWithOne) {
  Farm farm;
  const std::string token = "body-secret-3c9";
  write(farm.dir() / "client.token", token + "\n");
  farm.start_server({"--http-listen", "127.0.0.1:0", "--client-token-file", (farm.dir() / "client.token").string()});
  const int port = http_port(farm);
  httplib::Client http("127.0.0.1", port);
  auto warm = http.Get("/api/farm", bearer(token));  // the HTTP side's threads exist before the baseline
  ASSERT_TRUE(warm && warm->status == 200);
  const double baseline = peak_rss_mib(farm.server().pid());
  const auto head = [](const std::string& path, const std::string& auth, const std::string& length) {
    return "POST " + path + " HTTP/1.1\r\nHost: 127.0.0.1\r\nContent-Type: application/json\r\n" + auth + length +
           "\r\n";
  };
  constexpr int64_t kBig = int64_t(300) << 20;
  const std::string big = "Content-Length: " + std::to_string(kBig) + "\r\n";
  for (const char* path : {"/api/jobs/j1/cancel", "/api/jobs/j1/priority", "/metrics", "/no/such/route"}) {
    const Answer a = post_streaming(port, head(path, "", big), kBig);
    EXPECT_EQ(a.status, 401) << path << ": " << a.text;
  }
  // Of unknown length: chunked, or no length at all (read until the connection closes).
  const Answer chunked = post_streaming(port, head("/api/jobs/j1/cancel", "", "Transfer-Encoding: chunked\r\n"), kBig);
  EXPECT_EQ(chunked.status, 401) << chunked.text;
  const Answer unsized = post_streaming(port, head("/api/jobs/j1/cancel", "", ""), kBig);
  EXPECT_EQ(unsized.status, 401) << unsized.text;
  // With the token: the body limit, named.
  const std::string auth = "Authorization: Bearer " + token + "\r\n";
  const Answer over = post_streaming(port, head("/api/jobs/j1/priority", auth, big), kBig);
  EXPECT_EQ(over.status, 413) << over.text;
  EXPECT_NE(over.text.find("over this monitor's limit 4096 bytes"), std::string::npos) << over.text;
  const Answer chunked_ok =
      post_streaming(port, head("/api/jobs/j1/cancel", auth, "Transfer-Encoding: chunked\r\n"), kBig);
  EXPECT_EQ(chunked_ok.status, 411) << chunked_ok.text;
  const Answer unsized_ok = post_streaming(port, head("/api/jobs/j1/cancel", auth, ""), kBig);
  EXPECT_EQ(unsized_ok.status, 411) << unsized_ok.text;
  // A body within the limit still reaches its route (the job does not exist).
  auto small = http.Post("/api/jobs/j1/priority", bearer(token), R"({"priority":-2147483648})", "application/json");
  ASSERT_TRUE(small);
  EXPECT_EQ(small->status, 404) << small->body;
  const double peak = peak_rss_mib(farm.server().pid());
  std::printf("coordinator peak RSS %.1f MiB before the bodies, %.1f MiB after\n", baseline, peak);
  if (kRssMeaningful) {
    EXPECT_LT(peak - baseline, 100.0);
  }
  EXPECT_TRUE(farm.server().running()) << farm.server().log();
}

// A request's head is bounded too, before anything of it is checked: cpp-httplib 0.11 reads a
// request line or a header line until its newline, however long, and any number of header lines.
// An unauthenticated client that sent 393 MiB of request line took the coordinator from 27 MiB to
// 540 MiB before the 10 s head deadline cut it. Now a connection that sends more than a request's
// budget before its answer is cut at once, by line or by count of headers.
TEST(MonitorHttp, AnEndlessRequestHeadIsCutAtItsBudget) {
  Farm farm;
  write(farm.dir() / "client.token", "head-secret-77a\n");
  farm.start_server({"--http-listen", "127.0.0.1:0", "--client-token-file", (farm.dir() / "client.token").string()});
  const int port = http_port(farm);
  httplib::Client http("127.0.0.1", port);
  ASSERT_TRUE(http.Get("/"));  // the HTTP side's threads exist before the baseline
  const double baseline = peak_rss_mib(farm.server().pid());
  constexpr int64_t kEndless = int64_t(300) << 20;
  // A request line that never ends (zeros, no newline).
  const Answer line = post_streaming(port, "GET /", kEndless);
  EXPECT_LT(line.body_sent, kEndless) << "the server read a 300 MiB request line";
  // Header lines that never end, each short.
  std::string pad;
  while (pad.size() < (size_t(256) << 10)) pad += "X-Pad: " + std::to_string(pad.size()) + "\r\n";
  const Answer headers = post_streaming(port, "GET /api/farm HTTP/1.1\r\nHost: 127.0.0.1\r\n", kEndless, pad);
  EXPECT_LT(headers.body_sent, kEndless) << "the server read 300 MiB of headers";
  const double peak = peak_rss_mib(farm.server().pid());
  std::printf("coordinator peak RSS %.1f MiB before the heads, %.1f MiB after\n", baseline, peak);
  if (kRssMeaningful) {
    EXPECT_LT(peak - baseline, 100.0);
  }
  auto after = http.Get("/api/farm", bearer("head-secret-77a"));
  ASSERT_TRUE(after) << httplib::to_string(after.error());
  EXPECT_EQ(after->status, 200);
  EXPECT_NE(farm.server().log().find("HTTP: closed"), std::string::npos) << farm.server().log();
}

TEST(MonitorHttp, MutualTlsRequiresAClientCertificateWhoseNameIsTheCaller) {
  // The refused handshake may leave this client writing to a closed socket: an error, not a signal.
  signal(SIGPIPE, SIG_IGN);
  Farm farm;
  const std::string d = farm.dir().string();
  const std::string key = "-newkey ec -pkeyopt ec_paramgen_curve:prime256v1 -nodes";
  const std::string q = " 2>>openssl.log";
  for (const std::string& cmd :
       {"openssl req -x509 " + key + " -keyout ca.key -out ca.pem -days 2 -subj '/CN=Monitor Test CA'" + q,
        "openssl req " + key + " -keyout server.key -out server.csr -subj /CN=localhost" + q,
        "printf 'subjectAltName=IP:127.0.0.1\\n' > server.ext && openssl x509 -req -in server.csr -CA ca.pem -CAkey "
        "ca.key -CAcreateserial -days 2 -out server.pem -extfile server.ext" + q,
        "openssl req " + key + " -keyout client.key -out client.csr -subj /CN=render-ops" + q,
        "printf 'extendedKeyUsage=clientAuth\\n' > client.ext && openssl x509 -req -in client.csr -CA ca.pem -CAkey "
        "ca.key -CAcreateserial -days 2 -out client.pem -extfile client.ext" + q}) {
    ASSERT_EQ(std::system(("cd " + d + " && " + cmd).c_str()), 0) << cmd;
  }
  farm.start_server({"--http-listen", "127.0.0.1:0", "--tls-cert", d + "/server.pem", "--tls-key", d + "/server.key",
                     "--tls-ca", d + "/ca.pem", "--admin", "cn:render-ops"});
  const int port = http_port(farm);
  // Without a client certificate the handshake fails: no answer at all.
  httplib::SSLClient anonymous("127.0.0.1", port);
  anonymous.set_ca_cert_path((d + "/ca.pem").c_str());
  anonymous.enable_server_certificate_verification(true);
  auto refused = anonymous.Get("/api/farm");
  EXPECT_FALSE(refused && refused->status == 200);
  // With one, the certificate's CN is the caller, as on the gRPC side.
  httplib::SSLClient ops("127.0.0.1", port, d + "/client.pem", d + "/client.key");
  ops.set_ca_cert_path((d + "/ca.pem").c_str());
  ops.enable_server_certificate_verification(true);
  auto me = ops.Get("/api/whoami");
  ASSERT_TRUE(me) << httplib::to_string(me.error());
  ASSERT_EQ(me->status, 200) << me->body;
  EXPECT_EQ(json::parse(me->body).at("identity"), "cn:render-ops");
  EXPECT_TRUE(json::parse(me->body).at("admin").get<bool>());
}

TEST(MonitorPrometheus, PrometheusScrapesTilesCompletedEqualToTheJobsTiles) {
  if (!fs::exists("/usr/bin/prometheus")) GTEST_SKIP() << "/usr/bin/prometheus not installed (Debian prometheus)";
  Farm farm;
  farm.start_server({"--http-listen", "127.0.0.1:0"});
  const int port = http_port(farm);
  farm.start_worker("w1");
  farm.start_worker("w2");
  const int prom_port = free_port();
  const auto prometheus = start_prometheus(farm, port, prom_port);
  CliResult r = farm.cli({"submit", kScene.string(), "--coordinator", farm.address(), "-o",
                          (farm.dir() / "out" / "frame_####.exr").string(), "--tile", "16"});
  ASSERT_EQ(r.code, 0) << r.output;
  const int tiles = 3 * kTilesPerFrame;
  httplib::Client api("127.0.0.1", prom_port);
  double seen = -1;
  std::string last;
  for (int i = 0; i < 600 && seen != tiles; ++i) {  // up to a minute: Prometheus starts, then scrapes each second
    std::this_thread::sleep_for(100ms);
    auto q = api.Get("/api/v1/query?query=tessera_tiles_completed_total");
    if (!q || q->status != 200) continue;
    last = q->body;
    const json result = json::parse(q->body).at("data").at("result");
    if (result.size() == 1) seen = std::stod(result[0].at("value")[1].get<std::string>());
  }
  EXPECT_EQ(seen, tiles) << "last answer: " << last << "\n" << prometheus->log();
  // The rays the CLI reported went through the same counter path.
  auto rays = api.Get("/api/v1/query?query=tessera_rays_traced_total");
  ASSERT_TRUE(rays);
  const json rr = json::parse(rays->body).at("data").at("result");
  ASSERT_EQ(rr.size(), 1u) << rays->body;
  EXPECT_GT(std::stod(rr[0].at("value")[1].get<std::string>()), 0.0);
}

// The level an autoscaler reads (docker/k8s/keda: KEDA's Prometheus scaler on
// sum(tessera_work_seconds)), through a real Prometheus: a job waiting with no worker and no tile
// ever timed counts a nominal second a tile (a scaler at zero workers must see it); a job waiting
// after others were rendered counts the mean tile time the coordinator measured
// (tessera_tile_render_seconds' sum over its count, read from /metrics); a cancelled one nothing.
TEST(MonitorPrometheus, TheWorkGaugeIsWhatAnAutoscalerReads) {
  if (!fs::exists("/usr/bin/prometheus")) GTEST_SKIP() << "/usr/bin/prometheus not installed (Debian prometheus)";
  Farm farm;
  farm.start_server({"--http-listen", "127.0.0.1:0"});
  const int port = http_port(farm);
  const int prom_port = free_port();
  const auto prometheus = start_prometheus(farm, port, prom_port);
  httplib::Client api("127.0.0.1", prom_port);
  // Polls the scaler's query until it is within 1e-6 (relative) of `want`; returns the last value.
  const auto scaler_sees = [&](double want) {
    double seen = -1;
    for (int i = 0; i < 600; ++i) {  // up to a minute: Prometheus starts, then scrapes each second
      auto q = api.Get("/api/v1/query?query=sum(tessera_work_seconds)");
      if (q && q->status == 200) {
        const json result = json::parse(q->body).at("data").at("result");
        if (result.size() == 1) seen = std::stod(result[0].at("value")[1].get<std::string>());
        if (std::abs(seen - want) <= 1e-6 * std::max(1.0, want)) break;
      }
      std::this_thread::sleep_for(100ms);
    }
    return seen;
  };
  const int tiles = 3 * kTilesPerFrame;
  const auto submit = [&] {
    CliResult s = farm.cli({"submit", kScene.string(), "--coordinator", farm.address(), "--tile", "16", "--detach"});
    EXPECT_EQ(s.code, 0) << s.output;
    return job_id_from(s.output);
  };

  const std::string first = submit();
  EXPECT_DOUBLE_EQ(scaler_sees(tiles * 1.0), tiles * 1.0) << "no worker, no tile timed: a second a tile";

  // A worker renders it and leaves; the same job again waits with nobody to render it.
  Process& w = farm.start_worker("w1");
  ASSERT_EQ(farm.cli({"watch", first, "--coordinator", farm.address(), "-o",
                      (farm.dir() / "out" / "frame_####.exr").string()})
                .code,
            0);
  w.signal(SIGTERM);
  ASSERT_EQ(w.wait(30s), 0);
  const std::string second = submit();
  httplib::Client coordinator("127.0.0.1", port);
  auto m = coordinator.Get("/metrics");
  ASSERT_TRUE(m && m->status == 200);
  std::smatch sum, count;
  ASSERT_TRUE(std::regex_search(m->body, sum, std::regex(R"(\ntessera_tile_render_seconds_sum ([0-9.e+-]+))")));
  ASSERT_TRUE(std::regex_search(m->body, count, std::regex(R"(\ntessera_tile_render_seconds_count ([0-9]+))")));
  ASSERT_EQ(std::stoi(count[1]), tiles);
  const double want = tiles * (std::stod(sum[1]) / std::stod(count[1]));
  const double seen = scaler_sees(want);
  EXPECT_NEAR(seen, want, 1e-6 * want) << "the measured mean tile time, times the tiles waiting";
  EXPECT_NE(seen, tiles * 1.0);

  ASSERT_EQ(farm.cli({"cancel", second, "--coordinator", farm.address()}).code, 0);
  EXPECT_EQ(scaler_sees(0), 0.0) << "a cancelled job is no work";
}

TEST(MonitorBrowser, ChromiumShowsTheJobTheWorkersTheFinishedFrameAndCancels) {
  for (const char* p : {"/usr/bin/chromium", "/usr/bin/chromedriver", "/usr/bin/python3"}) {
    if (!fs::exists(p)) GTEST_SKIP() << p << " not installed (Debian chromium, chromium-driver, python3-selenium)";
  }
  Farm farm;
  const std::string token = "monitor-secret-5e1";
  write(farm.dir() / "client.token", token + "\n");
  farm.start_server({"--http-listen", "127.0.0.1:0", "--client-token-file", (farm.dir() / "client.token").string()});
  const int port = http_port(farm);
  // Slowed so that the page sees the job running and the second job is still live when cancelled.
  farm.start_worker("w1", 1, 200);
  farm.start_worker("w2", 1, 200);
  std::unique_ptr<Process> rays;
  const std::string rays_address = start_rays(farm, &rays, {"--announce-seconds", "0.2"});
  const std::vector<std::string> auth{"--coordinator", farm.address(), "--token-file",
                                      (farm.dir() / "client.token").string(), "--tile", "16"};
  auto with = [&](std::vector<std::string> args) {
    args.insert(args.end(), auth.begin(), auth.end());
    return args;
  };
  // The page is open (past its login) before the jobs are submitted: it sees them render.
  const fs::path out = farm.dir() / "browser";
  fs::create_directories(out);
  Process browser({"/usr/bin/python3", source("tests/farm/monitor_browser.py").string(),
                   "http://127.0.0.1:" + std::to_string(port) + "/", token, out.string()},
                  farm.dir() / "browser.log");
  for (int i = 0; i < 1200 && !fs::exists(out / "ready") && browser.running(); ++i) std::this_thread::sleep_for(50ms);
  ASSERT_TRUE(fs::exists(out / "ready")) << browser.log();
  auto done_cli = farm.cli_async(with({"submit", kScene.string(), "--frames", "0", "--name", "monitored", "-o",
                                       (farm.dir() / "out" / "frame_####.exr").string()}),
                                 "submit-done.log");
  const std::string done_job = wait_job_id(*done_cli);
  ASSERT_FALSE(done_job.empty()) << done_cli->log();
  auto cancel_cli = farm.cli_async(with({"submit", kScene.string(), "--name", "to-cancel", "-o",
                                         (farm.dir() / "out2" / "frame_####.exr").string()}),
                                   "submit-cancel.log");
  const std::string cancel_job = wait_job_id(*cancel_cli);
  ASSERT_FALSE(cancel_job.empty()) << cancel_cli->log();
  write(out / "jobs.json.tmp", json{{"done", done_job}, {"cancel", cancel_job}}.dump());
  fs::rename(out / "jobs.json.tmp", out / "jobs.json");
  ASSERT_EQ(browser.wait(150s), 0) << browser.log() << "\n" << farm.server().log();
  const std::string log = browser.log();
  const json report = json::parse(log.substr(log.rfind("\n{") == std::string::npos ? 0 : log.rfind("\n{") + 1));
  EXPECT_TRUE(report.at("asked_for_token").get<bool>());
  EXPECT_EQ(report.at("job").at("id"), done_job);
  EXPECT_EQ(report.at("job").at("name"), "monitored");
  EXPECT_EQ(report.at("workers"), json::array({"w1", "w2"}));
  EXPECT_EQ(report.at("ray_servers"), json::array({rays_address}));
  EXPECT_EQ(report.at("preview_tiles"), kTilesPerFrame);
  EXPECT_EQ(report.at("frames_rows"), 1);
  EXPECT_TRUE(report.at("cancelled").get<bool>());

  // The frame the CLI wrote, tone-mapped by `tessera convert` (8-bit PNG, clamp, no dither),
  // equals what the browser decoded from the preview, pixel for pixel.
  ASSERT_EQ(done_cli->wait(60s), 0) << done_cli->log();
  const fs::path ref = farm.dir() / "reference.png";
  CliResult conv = farm.cli({"convert", (farm.dir() / "out" / "frame_0000.exr").string(), ref.string()});
  ASSERT_EQ(conv.code, 0) << conv.output;
  const color::Rgb8Image want = color::read_png_rgb8(ref.string());
  const json size = json::parse(read_text(out / "preview.json"));
  ASSERT_EQ(size.at("width"), want.width);
  ASSERT_EQ(size.at("height"), want.height);
  const std::string got = read_text(out / "preview.rgba");
  ASSERT_EQ(got.size(), size_t(want.width) * size_t(want.height) * 4);
  int64_t differing = 0;
  std::string first;
  for (size_t p = 0; p < size_t(want.width) * size_t(want.height); ++p) {
    for (size_t c = 0; c < 3; ++c) {
      if (uint8_t(got[p * 4 + c]) != want.pixels[p * 3 + c]) {
        if (differing++ == 0) {
          first = "pixel " + std::to_string(p) + " channel " + std::to_string(c) + ": browser " +
                  std::to_string(uint8_t(got[p * 4 + c])) + ", reference " + std::to_string(want.pixels[p * 3 + c]);
        }
      }
    }
  }
  EXPECT_EQ(differing, 0) << first;

  // The CLI watching the other job reports it cancelled (exit code 3).
  EXPECT_EQ(cancel_cli->wait(60s), 3) << cancel_cli->log();
  EXPECT_NE(cancel_cli->log().find("job " + cancel_job + " was cancelled"), std::string::npos) << cancel_cli->log();

  // The screenshots are docs/monitor.png's and docs/monitor-farm.png's source: refreshed there
  // with TESSERA_UPDATE_DOCS=1.
  ASSERT_TRUE(fs::exists(out / "monitor.png"));
  if (const char* update = std::getenv("TESSERA_UPDATE_DOCS"); update && std::string(update) == "1") {
    for (const char* name : {"monitor.png", "monitor-farm.png"}) {
      fs::copy_file(out / name, source(std::string("docs/") + name), fs::copy_options::overwrite_existing);
    }
  }
}

}  // namespace
}  // namespace tessera::farmtest
