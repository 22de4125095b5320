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

// Throws std::invalid_argument(message).
[[noreturn]] void ThrowInvalid(const std::string& message);

// "where: message" when `where` is non-empty, else "message".
std::string Where(const std::string& where, const std::string& message);

// Shortest round-trip text of a double (for error messages).
std::string FormatNumber(double value);

}  // namespace aos
