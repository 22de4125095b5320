#pragma once
// JSON documents read from files, with errors that say where. Every reader of a JSON format
// (light field, camera, scene, stack, pose record) parses through ParseJsonText / ParseJsonFile
// and runs its field reading under WithJsonErrorsNamed, so a syntax error, a number that
// overflows (1e999), invalid UTF-8 or a value of the wrong type becomes one
// std::invalid_argument naming the file and the key path:
//   "cam.json: /format: type must be string, but is number"
//   "lf.json: /views/3/cam_from_world/translation/0: not valid JSON (number overflow parsing '1e999')"
// Internal header: it includes nlohmann/json, a private dependency of the core.
#include <string>
#include <utility>

#include <nlohmann/json.hpp>

namespace aos {

// Arrays and objects nest at most this deep in any aos file (far more than any format needs).
inline constexpr int kMaxJsonDepth = 256;

// Parses `text` (the contents of `path`, which is only named in errors). Refuses documents
// nested deeper than kMaxJsonDepth.
nlohmann::json ParseJsonText(const std::string& text, const std::string& path);

// Reads (regular files only, size-bounded; see ReadTextFile) and parses `path`.
nlohmann::json ParseJsonFile(const std::string& path);

// Rethrows a library error met while reading the document of `path` as std::invalid_argument
// naming the file and, where the library knows it, the key path.
[[noreturn]] void RethrowJsonError(const std::string& path, const nlohmann::json::exception& error);

// Runs `read` and names `path` in any nlohmann::json error it throws.
template <class Read>
auto WithJsonErrorsNamed(const std::string& path, Read&& read) -> decltype(read()) {
  try {
    return std::forward<Read>(read)();
  } catch (const nlohmann::json::exception& error) {
    RethrowJsonError(path, error);
  }
}

}  // namespace aos
