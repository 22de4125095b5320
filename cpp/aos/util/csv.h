#pragma once
// Comma-separated values as aos's text readers take them (telemetry logs, positions files): one
// tokenizer, so every reader accepts the same files and refuses the same mistakes.
//
// The fields of RFC 4180, with the conveniences that hand-written and exported files need:
// - one record per line, lines ending in LF or CRLF;
// - a field in double quotes may hold commas, line breaks and doubled quotes ("" is one "); the
//   record then continues past the line break;
// - blanks (spaces, tabs) around a field are dropped; inside quotes they are kept;
// - a UTF-8 byte-order mark at the start of the text is skipped (spreadsheets write one);
// - blank lines, and lines whose first non-blank character is '#' (where a record would start),
//   are skipped;
// - a trailing comma gives a last, empty field ("a,b," has three fields).
// Throws std::invalid_argument "<path>: line N: ..." for a line that is not valid UTF-8, a quote
// left open at the end of the text (naming the line it opened on), text after a closing quote
// ("a"b) and a quote inside an unquoted field (a"b: quote the whole field and double the quote).
#include <string>
#include <vector>

namespace aos {

struct CsvRecord {
  int line = 0;                     // the line the record starts on, from 1
  std::vector<std::string> fields;  // at least one
};

// The records of `text` (a file's contents); `path` names the file in errors.
std::vector<CsvRecord> ParseCsv(const std::string& text, const std::string& path);

// The number a text field holds (all of it: strtod's syntax), finite; else std::invalid_argument
// "<where>: <field>: \"x\" is not a number" or "...: inf is not finite". For the fields of
// CSV and other text tables (telemetry logs, OpenDroneMap's geo.txt).
double ParseFiniteNumber(const std::string& text, const std::string& where,
                         const std::string& field);

// `text` as one CSV field (RFC 4180, as ParseCsv reads it back): quoted, inner quotes doubled,
// when it holds a comma, a quote, a line end or blanks at either end; as it is otherwise.
std::string CsvField(const std::string& text);

}  // namespace aos
