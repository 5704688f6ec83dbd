#include "server/dashboard_assets.h"

#include <stdexcept>

// Each file's bytes, between a start and an end symbol, by the assembler's .incbin (the paths
// are compile definitions; CMake lists the files as this object's dependencies).
#define INVR_EMBED(sym, path)                                               \
  __asm__(".section .rodata\n.global " #sym "\n.balign 16\n" #sym ":\n"     \
          ".incbin \"" path "\"\n.global " #sym "_end\n" #sym "_end:\n.byte 0\n.previous\n"); \
  extern "C" const char sym[], sym##_end[];

INVR_EMBED(invr_dashboard_index_html, INVR_DASHBOARD_DIR "/index.html")
INVR_EMBED(invr_dashboard_app_js, INVR_DASHBOARD_DIR "/app.js")
INVR_EMBED(invr_dashboard_style_css, INVR_DASHBOARD_DIR "/style.css")
INVR_EMBED(invr_dashboard_chart_js, INVR_CHARTJS)

namespace invr::server {

EmbeddedFile dashboardFile(const std::string& name) {
  auto file = [](const char* b, const char* e) { return EmbeddedFile{b, size_t(e - b)}; };
  if (name == "index.html") return file(invr_dashboard_index_html, invr_dashboard_index_html_end);
  if (name == "app.js") return file(invr_dashboard_app_js, invr_dashboard_app_js_end);
  if (name == "style.css") return file(invr_dashboard_style_css, invr_dashboard_style_css_end);
  if (name == "chart.min.js") return file(invr_dashboard_chart_js, invr_dashboard_chart_js_end);
  throw std::out_of_range("no embedded dashboard file '" + name + "'");
}

}  // namespace invr::server
