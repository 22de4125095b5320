#include "aos/util/csv.h"

#include <cmath>
#include <cstdlib>

#include "aos/util/error.h"

namespace aos {
namespace {

bool IsBlank(char c) { return c == ' ' || c == '\t'; }

std::string TrimBlanks(const std::string& text) {
  const size_t a = text.find_first_not_of(" \t\r"), b = text.find_last_not_of(" \t\r");
  return a == std::string::npos ? "" : text.substr(a, b - a + 1);
}

}  // namespace

std::vector<CsvRecord> ParseCsv(const std::string& text, const std::string& path) {
  size_t i = text.compare(0, 3, "\xEF\xBB\xBF") == 0 ? 3 : 0;
  const size_t n = text.size();
  const auto where = [&](int line) { return path + ": line " + std::to_string(line); };
  // Every line valid UTF-8 (so no multi-byte character is split by the scan below).
  for (size_t start = i, line = 1; start <= n; ++line) {
    size_t end = text.find('\n', start);
    if (end == std::string::npos) end = n;
    if (!IsValidUtf8(text.substr(start, end - start))) {
      ThrowInvalid(where(static_cast<int>(line)) + ": not valid UTF-8 text");
    }
    start = end + 1;
  }
  std::vector<CsvRecord> records;
  int line = 1;
  while (i < n) {
    // At the start of a line, outside a record: blank and comment lines are skipped.
    size_t first = i;
    while (first < n && (IsBlank(text[first]) || text[first] == '\r')) ++first;
    if (first >= n || text[first] == '\n' || text[first] == '#') {
      const size_t end = text.find('\n', first);
      if (end == std::string::npos) break;
      i = end + 1;
      ++line;
      continue;
    }
    CsvRecord record;
    record.line = line;
    while (true) {
      while (i < n && IsBlank(text[i])) ++i;
      if (i < n && text[i] == '"') {
        const int opened = line;
        std::string value;
        for (++i;; ++i) {
          if (i >= n) {
            ThrowInvalid(where(opened) + ": field " + std::to_string(record.fields.size() + 1) +
                         ": its opening quote is never closed");
          }
          if (text[i] == '"') {
            if (i + 1 < n && text[i + 1] == '"') {
              value += '"';
              ++i;
              continue;
            }
            ++i;
            break;
          }
          if (text[i] == '\n') ++line;
          value += text[i];
        }
        while (i < n && (IsBlank(text[i]) || text[i] == '\r')) ++i;
        if (i < n && text[i] != ',' && text[i] != '\n') {
          ThrowInvalid(where(line) + ": field " + std::to_string(record.fields.size() + 1) +
                       ": text after its closing quote (a quote inside a quoted field is "
                       "written twice: \"\")");
        }
        record.fields.push_back(std::move(value));
      } else {
        const size_t start = i;
        while (i < n && text[i] != ',' && text[i] != '\n') {
          if (text[i] == '"') {
            ThrowInvalid(where(line) + ": field " + std::to_string(record.fields.size() + 1) +
                         ": a quote inside an unquoted field (quote the whole field and write "
                         "the quote twice: \"a\"\"b\")");
          }
          ++i;
        }
        record.fields.push_back(TrimBlanks(text.substr(start, i - start)));
      }
      if (i < n && text[i] == ',') {
        ++i;
        continue;
      }
      if (i < n) ++i;  // the line break
      ++line;
      break;
    }
    records.push_back(std::move(record));
  }
  return records;
}

double ParseFiniteNumber(const std::string& text, const std::string& where,
                         const std::string& field) {
  char* end = nullptr;
  const double value = std::strtod(text.c_str(), &end);
  if (text.empty() || end != text.c_str() + text.size()) {
    ThrowInvalid(where + ": " + field + ": \"" + text + "\" is not a number");
  }
  if (!std::isfinite(value)) ThrowInvalid(where + ": " + field + ": " + text + " is not finite");
  return value;
}

std::string CsvField(const std::string& text) {
  const bool blank_ends = !text.empty() && (text.front() == ' ' || text.front() == '\t' ||
                                            text.back() == ' ' || text.back() == '\t');
  if (!blank_ends && text.find_first_of(",\"\r\n") == std::string::npos) return text;
  std::string quoted = "\"";
  for (char c : text) quoted += c == '"' ? std::string("\"\"") : std::string(1, c);
  return quoted + "\"";
}

}  // namespace aos
