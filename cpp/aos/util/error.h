#pragma once
// Errors. Bad user input throws std::invalid_argument whose message names the file, the entry and
// the field ("poses.json: image 17 (B05.png): M3x4: rotation is not orthonormal (...)"); pybind11
// turns it into ValueError. Cancellation from a progress sink throws aos::Cancelled. Library code
// never prints and never exits.
#include <stdexcept>
#include <string>

namespace aos {

// Thrown when a ProgressSink asked to stop (Ctrl-C from Python, for example).
class Cancelled : public std::runtime_error {
 public:
  Cancelled() : std::runtime_error("cancelled") {}
};

// Throws std::invalid_argument(OneLine(message)).
[[noreturn]] void ThrowInvalid(const std::string& message);

// The message as one line of valid UTF-8: line breaks (from a library's multi-line error text)
// become "; ", other control characters and bytes that are not valid UTF-8 become \xNN, so the
// CLI prints exactly one line and Python can always turn the message into a str.
std::string OneLine(const std::string& message);

// Error messages name the user's paths, not the temporary files outputs are written to:
// PendingFile and PendingFolder register each temporary path with the path the user gave, and
// ThrowInvalid (through UserPaths) writes the latter wherever the former appears in a message.
void RegisterPathAlias(const std::string& temporary_path, const std::string& user_path);
std::string UserPaths(const std::string& message);

// Whether `text` is valid UTF-8 (no overlong forms, no surrogates, nothing past U+10FFFF).
bool IsValidUtf8(const std::string& text);

// "where: message" when `where` is non-empty, else "message".
std::string Where(const std::string& where, const std::string& message);

// Shortest round-trip text of a double (for error messages).
std::string FormatNumber(double value);

}  // namespace aos
