// SPDX-License-Identifier: Apache-2.0
// The routes of the coordinator's HTTP listener:
//   GET  /, /static/NAME          the monitor page and its modules (no farm data: always served)
//   GET  /api/whoami              who the token makes the caller, and whether one is needed
//   GET  /api/farm                jobs and workers
//   GET  /api/jobs/ID[?frame=F]   one job: frames' times and errors, the preview's tile map
//   GET  /api/jobs/ID/preview.png[?frame=F&tonemap=T&exposure=EV]  the frame tone-mapped
//   POST /api/jobs/ID/cancel      as CancelJob
//   POST /api/jobs/ID/priority    {"priority": N}, as SetJobPriority
//   GET  /metrics                 Prometheus text format (when metrics are given)
// Every route but the page itself checks the client token as the gRPC API does
// (`Authorization: Bearer TOKEN`), first from the request's head, before any body is read (the
// listener's gate, http_listener.h): an unknown route too. Watching (the preview, the job page),
// cancelling and changing the priority need the permissions of job_access.h.
#pragma once

#include <set>
#include <string>

#include "farm/auth.h"

namespace tessera::server {

class FarmControl;
class FarmMetrics;
class HttpListener;
class MonitorFeed;

struct MonitorRoutes {
  FarmControl& coordinator;  // farm_control.h: what the pages read, cancelling, priorities
  MonitorFeed& feed;
  FarmMetrics* metrics = nullptr;  // null: no /metrics
  const farm::Authenticator& auth;
  std::set<std::string> admins;

  // The routes, and the gate that checks the token before a request's body is read.
  void install(HttpListener& listener) const;
};

}  // namespace tessera::server
