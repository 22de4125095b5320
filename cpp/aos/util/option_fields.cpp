#include "aos/util/option_fields.h"

namespace aos {

std::string Range::Text() const {
  const bool no_lo = std::isinf(lo) && lo < 0;
  const bool no_hi = std::isinf(hi) && hi > 0;
  std::string text;
  if (no_lo && no_hi) {
    text = "a number";
  } else if (lo == -std::numeric_limits<double>::max() && hi == std::numeric_limits<double>::max()) {
    text = "finite";
  } else if (no_hi || hi == std::numeric_limits<double>::max()) {
    text = (lo_open ? "> " : ">= ") + FormatNumber(lo);
    if (!no_hi) text += " and finite";
  } else if (no_lo) {
    text = (hi_open ? "< " : "<= ") + FormatNumber(hi);
  } else {
    text = std::string("in ") + (lo_open ? "(" : "[") + FormatNumber(lo) + ", " + FormatNumber(hi) +
           (hi_open ? ")" : "]");
  }
  if (has_special) text += " or " + FormatNumber(special);
  return text;
}

}  // namespace aos
