// The dashboard's files, embedded in invr-server at build time (server/dashboard/ and Debian's
// Chart.js): the binary serves them with no CDN and no internet.
#pragma once

#include <cstddef>
#include <string>

namespace invr::server {

struct EmbeddedFile {
  const char* data = nullptr;
  size_t size = 0;
};

// index.html, app.js, style.css or chart.min.js; throws std::out_of_range for another name.
EmbeddedFile dashboardFile(const std::string& name);

}  // namespace invr::server
