#include "aos/util/error.h"

#include <cstdint>
#include <cstdio>
#include <deque>
#include <mutex>
#include <utility>

namespace aos {
namespace {

// Length of the valid UTF-8 sequence starting at text[i], or 0 if none starts there.
size_t Utf8SequenceLength(const std::string& text, size_t i) {
  const auto byte = [&](size_t k) { return static_cast<uint8_t>(text[k]); };
  const uint8_t lead = byte(i);
  if (lead < 0x80) return 1;
  size_t length = 0;
  uint32_t code = 0;
  if ((lead & 0xE0) == 0xC0) {
    length = 2;
    code = lead & 0x1F;
  } else if ((lead & 0xF0) == 0xE0) {
    length = 3;
    code = lead & 0x0F;
  } else if ((lead & 0xF8) == 0xF0) {
    length = 4;
    code = lead & 0x07;
  } else {
    return 0;
  }
  if (i + length > text.size()) return 0;
  for (size_t k = 1; k < length; ++k) {
    if ((byte(i + k) & 0xC0) != 0x80) return 0;
    code = (code << 6) | (byte(i + k) & 0x3F);
  }
  static constexpr uint32_t kSmallest[5] = {0, 0, 0x80, 0x800, 0x10000};
  if (code < kSmallest[length] || code > 0x10FFFF || (code >= 0xD800 && code <= 0xDFFF)) return 0;
  return length;
}

struct PathAliases {
  std::mutex mutex;
  std::deque<std::pair<std::string, std::string>> aliases;  // oldest first
};

PathAliases& Aliases() {
  static PathAliases* aliases = new PathAliases();  // never destroyed: used during shutdown too
  return *aliases;
}

}  // namespace

void RegisterPathAlias(const std::string& temporary_path, const std::string& user_path) {
  if (temporary_path.empty()) return;
  PathAliases& table = Aliases();
  std::lock_guard<std::mutex> lock(table.mutex);
  table.aliases.emplace_back(temporary_path, user_path);
  // A long-running process (Python) writes many files; only recent ones can be in a message.
  if (table.aliases.size() > 4096) table.aliases.pop_front();
}

std::string UserPaths(const std::string& message) {
  std::string text = message;
  PathAliases& table = Aliases();
  std::lock_guard<std::mutex> lock(table.mutex);
  // Newest first: a temporary file of a temporary path (WriteImage into a PendingFile's
  // temporary name) maps back in two steps.
  for (auto it = table.aliases.rbegin(); it != table.aliases.rend(); ++it) {
    const auto& [temporary, user] = *it;
    for (size_t at = text.find(temporary); at != std::string::npos;
         at = text.find(temporary, at + user.size())) {
      text.replace(at, temporary.size(), user);
    }
  }
  return text;
}

bool IsValidUtf8(const std::string& text) {
  for (size_t i = 0; i < text.size();) {
    const size_t length = Utf8SequenceLength(text, i);
    if (length == 0) return false;
    i += length;
  }
  return true;
}

std::string OneLine(const std::string& message) {
  std::string line;
  line.reserve(message.size());
  size_t i = 0;
  // Trailing line breaks are dropped; inner ones (and runs of them) become one "; ".
  size_t end = message.size();
  while (end > 0 && (message[end - 1] == '\n' || message[end - 1] == '\r')) --end;
  while (i < end) {
    const char c = message[i];
    if (c == '\n' || c == '\r') {
      while (i < end && (message[i] == '\n' || message[i] == '\r' || message[i] == ' ')) ++i;
      line += "; ";
      continue;
    }
    const size_t length = Utf8SequenceLength(message, i);
    const bool control = length == 1 && (static_cast<uint8_t>(c) < 0x20 || c == 0x7F) && c != '\t';
    if (length == 0 || control) {
      char escaped[8];
      std::snprintf(escaped, sizeof(escaped), "\\x%02X", static_cast<unsigned>(static_cast<uint8_t>(c)));
      line += escaped;
      ++i;
      continue;
    }
    line.append(message, i, length);
    i += length;
  }
  return line;
}

void ThrowInvalid(const std::string& message) {
  throw std::invalid_argument(OneLine(UserPaths(message)));
}

std::string Where(const std::string& where, const std::string& message) {
  return where.empty() ? message : where + ": " + message;
}

std::string FormatNumber(double value) {
  char buffer[64];
  std::snprintf(buffer, sizeof(buffer), "%.10g", value);
  return buffer;
}

}  // namespace aos
