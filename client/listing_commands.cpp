// SPDX-License-Identifier: Apache-2.0
// `tessera workers` and `tessera rayservers`: what is connected to the coordinator, as a table or
// JSON. Both are one List* call printed by run_listing; each says only how its rows look.
#include <cstdio>
#include <iostream>
#include <memory>
#include <nlohmann/json.hpp>
#include <string>

#include "commands.h"
#include "duration_text.h"
#include "farm_command.h"

namespace tessera::cli {

namespace v1 = tessera::v1;

namespace {

struct ListingArgs {
  std::string coordinator;
  SecurityFlags security;
  bool json = false;
};

// A listing: the call that fetches it and how its rows print.
template <class Response, class Row>
struct Listing {
  const char* what;  // names the call in its error message: "listing workers"
  grpc::Status (*call)(v1::ClientService::Stub& stub, grpc::ClientContext* ctx, Response* response);
  const google::protobuf::RepeatedPtrField<Row>& (*rows)(const Response& response);
  nlohmann::json (*json)(const Row& row);  // one element of the --json array
  void (*none)(const std::string& address);  // there are no rows
  void (*header)();
  void (*row)(const Row& row);
};

template <class Response, class Row>
int run_listing(const ListingArgs& a, const Listing<Response, Row>& listing) {
  FarmClient client = connect(a.coordinator, a.security);
  Response resp;
  auto ctx = client.context();
  grpc::Status s = listing.call(client.stub(), ctx.get(), &resp);
  if (!s.ok()) throw CommandError{kExitFailure, client.describe(s, listing.what)};
  const google::protobuf::RepeatedPtrField<Row>& rows = listing.rows(resp);
  if (a.json) {
    nlohmann::json out = nlohmann::json::array();
    for (const Row& r : rows) out.push_back(listing.json(r));
    std::cout << out.dump(2) << "\n";
    return 0;
  }
  if (rows.empty()) {
    listing.none(client.address());
    return 0;
  }
  listing.header();
  for (const Row& r : rows) listing.row(r);
  return 0;
}

const Listing<v1::ListWorkersResponse, v1::WorkerInfo> kWorkers{
    .what = "listing workers",
    .call = [](v1::ClientService::Stub& stub, grpc::ClientContext* ctx, v1::ListWorkersResponse* resp) {
      return stub.ListWorkers(ctx, {}, resp);
    },
    .rows = [](const v1::ListWorkersResponse& resp) -> const auto& { return resp.workers(); },
    .json = [](const v1::WorkerInfo& w) -> nlohmann::json {
      return {{"worker_id", w.worker_id()}, {"name", w.name()}, {"peer", w.peer()},
              {"threads", w.threads()}, {"embree_isa", w.embree_isa()},
              {"tiles_in_flight", w.tiles_in_flight()}, {"tiles_done", w.tiles_done()},
              {"results_refused", w.results_refused()}, {"rays", w.rays()},
              {"render_seconds", w.render_seconds()}, {"connected_seconds", w.connected_seconds()},
              {"since_heartbeat_seconds", w.since_heartbeat_seconds()}};
    },
    .none = [](const std::string& address) { std::printf("no workers connected to %s\n", address.c_str()); },
    .header =
        [] {
          std::printf("%-4s %-20s %-22s %7s %-20s %9s %8s %8s %8s\n", "ID", "NAME", "PEER", "THREADS", "ISA",
                      "IN-FLIGHT", "TILES", "MRAYS/S", "UP");
        },
    .row =
        [](const v1::WorkerInfo& w) {
          const double mrays =
              w.render_seconds() > 0 ? double(w.rays()) / w.render_seconds() * w.threads() / 1e6 : 0;
          std::printf("%-4s %-20s %-22s %7d %-20s %9d %8lld %8.1f %8s\n", w.worker_id().c_str(), w.name().c_str(),
                      w.peer().c_str(), w.threads(), w.embree_isa().c_str(), w.tiles_in_flight(),
                      (long long)w.tiles_done(), mrays, format_duration(w.connected_seconds()).c_str());
        },
};

const Listing<v1::ListRayServersResponse, v1::RayServerInfo> kRayServers{
    .what = "listing ray servers",
    .call = [](v1::ClientService::Stub& stub, grpc::ClientContext* ctx, v1::ListRayServersResponse* resp) {
      return stub.ListRayServers(ctx, {}, resp);
    },
    .rows = [](const v1::ListRayServersResponse& resp) -> const auto& { return resp.servers(); },
    .json = [](const v1::RayServerInfo& r) -> nlohmann::json {
      const v1::RayServerDescription& d = r.server();
      return {{"server_id", d.server_id()}, {"address", d.address()}, {"threads", d.threads()},
              {"embree_isa", d.embree_isa()}, {"max_batch_rays", d.max_batch_rays()}, {"tls", d.tls()},
              {"client_token", d.client_token()}, {"version", d.version()}, {"requests", d.requests()},
              {"rays", d.rays()}, {"rays_in_flight", d.rays_in_flight()}, {"peer", r.peer()},
              {"up_seconds", r.up_seconds()}, {"since_announcement_seconds", r.since_announcement_seconds()},
              {"expiry_ms", r.expiry_ms()}};
    },
    .none =
        [](const std::string& address) {
          std::printf("no ray servers announced to %s (start one with: tessera-rays --coordinator %s)\n",
                      address.c_str(), address.c_str());
        },
    .header =
        [] {
          std::printf("%-16s %-22s %7s %-20s %-9s %10s %12s %9s %8s %6s\n", "ID", "ADDRESS", "THREADS", "ISA",
                      "SECURITY", "REQUESTS", "RAYS", "IN-FLIGHT", "UP", "SEEN");
        },
    .row =
        [](const v1::RayServerInfo& r) {
          const v1::RayServerDescription& d = r.server();
          const std::string security = std::string(d.tls() ? "tls" : "plain") + (d.client_token() ? "+tok" : "");
          std::printf("%-16s %-22s %7d %-20s %-9s %10llu %12llu %9llu %8s %5.1fs\n", d.server_id().c_str(),
                      d.address().c_str(), d.threads(), d.embree_isa().c_str(), security.c_str(),
                      (unsigned long long)d.requests(), (unsigned long long)d.rays(),
                      (unsigned long long)d.rays_in_flight(), format_duration(r.up_seconds()).c_str(),
                      r.since_announcement_seconds());
        },
};

void add_listing_command(CLI::App& app, const char* name, const char* description,
                         const std::function<int(const ListingArgs&)>& run) {
  auto a = std::make_shared<ListingArgs>();
  CLI::App* cmd = app.add_subcommand(name, description);
  add_coordinator_option(cmd, &a->coordinator, &a->security);
  cmd->add_flag("--json", a->json, "Machine-readable output");
  cmd->callback([a, name, run] { guarded(name, [&] { return run(*a); }); });
}

}  // namespace

void register_listing_commands(CLI::App& app) {
  add_listing_command(app, "workers", "List the workers connected to the coordinator",
                      [](const ListingArgs& a) { return run_listing(a, kWorkers); });
  add_listing_command(
      app, "rayservers",
      "List the ray servers (tessera-rays) announced to the coordinator, which `tessera rays` picks from",
      [](const ListingArgs& a) { return run_listing(a, kRayServers); });
}

}  // namespace tessera::cli
