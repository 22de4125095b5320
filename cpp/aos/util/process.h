#pragma once
// Running an external program (COLMAP) and streaming its output.
//
// Contract
// - RunProcess starts argv[0] (looked up on PATH when it has no '/') with the arguments
//   argv[1..], stdin from /dev/null, stdout and stderr merged into one pipe. Every output line
//   (without its newline; '\r' also ends a line) goes to on_line on the calling thread as it
//   arrives. The call returns the program's exit status (0..255), or 128 + N when signal N
//   ended it.
// - `cancelled` is polled at least every 100 ms; when it returns true the program gets SIGTERM,
//   then SIGKILL after 2 s, and RunProcess throws aos::Cancelled once it has exited. No child
//   process is ever left behind.
// - Throws std::invalid_argument "<argv[0]>: not found (...)" when the program cannot be
//   started (missing, not executable).
#include <functional>
#include <string>
#include <vector>

namespace aos {

// Whether `program` can be started: an executable file (path with '/') or one found on PATH.
bool ProgramExists(const std::string& program);

int RunProcess(const std::vector<std::string>& argv,
               const std::function<void(const std::string& line)>& on_line,
               const std::function<bool()>& cancelled = nullptr);

}  // namespace aos
