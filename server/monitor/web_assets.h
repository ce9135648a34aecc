// SPDX-License-Identifier: Apache-2.0
// The monitor's page, styles and JavaScript modules (server/monitor/web/), compiled into the
// server by embed_web.cmake: the coordinator serves them without files beside it and without a
// Node build step (plain ES modules, no npm packages).
#pragma once

#include <string_view>

namespace tessera::server {

struct WebAsset {
  std::string_view content_type;
  std::string_view bytes;
};

// The asset at `path` ("index.html", "monitor.js", ...), or nullptr.
const WebAsset* web_asset(std::string_view path);

}  // namespace tessera::server
