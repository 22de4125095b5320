#pragma once
// The browser viewer's own settings (the server in python/aos/viewer: where it listens, how many
// pages it serves, whether it opens a browser). Declared here, in the one field table every
// option has (util/option_fields.h), so that `aos-render view`'s flags, `aos.ViewerOptions` and
// `aos.view(...)`'s defaults, and the CLI's hand-off to Python come from one definition.
//
// Contract
// - host: the address to listen on; a loopback address by default. Anything else makes the
//   viewer reachable from other machines (the viewer warns); never empty.
// - port: TCP port, 0..65535; 0 = any free port.
// - max_pages: pages (browser tabs, WebSockets) served at once, 1..4096; the next is refused
//   until one closes.
// - render_workers: threads rendering page requests, 1..64.
// - open_browser: true / false, or unset = where a desktop session exists.
// Check() throws std::invalid_argument naming the field.
#include <optional>
#include <string>

#include "aos/util/error.h"
#include "aos/util/option_fields.h"

namespace aos {

struct ViewerOptions {
  std::string host = "127.0.0.1";
  int port = 0;
  int max_pages = 32;
  int render_workers = 1;
  std::optional<bool> open_browser;

  void Check() const {
    CheckFieldRanges(*this);
    if (host.empty()) ThrowInvalid("host: must name an address (127.0.0.1 = this machine only)");
  }

  // The field table (util/option_fields.h): every field once, in declaration order.
  template <class Visit>
  static void Fields(Visit&& field) {
    using O = ViewerOptions;
    field(OptionField("host", &O::host, "", Range::Any(),
                      "Address to listen on; anything but a loopback address makes the viewer "
                      "reachable from other machines (a warning says so)."));
    field(OptionField("port", &O::port, "", Range::Closed(0, 65535),
                      "TCP port; 0 = any free port."));
    field(OptionField("max_pages", &O::max_pages, "", Range::Closed(1, 4096),
                      "Pages (browser tabs) served at once; the next is refused until one "
                      "closes."));
    field(OptionField("render_workers", &O::render_workers, "", Range::Closed(1, 64),
                      "Threads rendering the pages' requests."));
    field(OptionField("open_browser", &O::open_browser, "", Range::Any(),
                      "Open a browser on the viewer's page: True, False, or None = where a "
                      "desktop session exists."));
  }
};

}  // namespace aos
