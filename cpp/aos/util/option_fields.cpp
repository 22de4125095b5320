#include "aos/util/option_fields.h"

namespace aos {

std::vector<std::string> Range::Choices() const {
  std::vector<std::string> values;
  if (choices == nullptr) return values;
  std::string current;
  for (const char* c = choices;; ++c) {
    if (*c == '|' || *c == '\0') {
      values.push_back(current);
      current.clear();
      if (*c == '\0') break;
    } else {
      current += *c;
    }
  }
  return values;
}

bool Range::ContainsText(const std::string& value) const {
  if (choices == nullptr) return true;
  for (const std::string& choice : Choices()) {
    if (value == choice) return true;
  }
  return false;
}

std::string FlagOfField(const std::string& name, const char* flag) {
  if (flag != nullptr) return std::string("--") + flag;
  if (name == "num_threads") return "--threads";
  std::string text = "--" + name;
  for (char& c : text) {
    if (c == '_') c = '-';
  }
  return text;
}

std::string Range::Text() const {
  if (choices != nullptr) {
    const std::vector<std::string> values = Choices();
    std::string text = "one of ";
    for (size_t i = 0; i < values.size(); ++i) {
      text += (i == 0 ? "" : i + 1 == values.size() ? " or " : ", ") + values[i];
    }
    return text;
  }
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
