#include "aos/util/json_file.h"

#include <vector>

#include "aos/util/error.h"
#include "aos/util/file_util.h"

namespace aos {
namespace {

// The library's message without its "[json.exception.type_error.302] " prefix, with the key path
// it adds under JSON_DIAGNOSTICS ("(/a/0) ...") moved to the front as "/a/0: ...".
std::string Describe(const nlohmann::json::exception& error) {
  std::string message = error.what();
  if (message.rfind("[json.exception.", 0) == 0) {
    const size_t end = message.find("] ");
    if (end != std::string::npos) message = message.substr(end + 2);
  }
  if (message.rfind("(/", 0) == 0 || message.rfind("() ", 0) == 0) {
    const size_t end = message.find(") ");
    if (end != std::string::npos) {
      const std::string path = message.substr(1, end - 1);
      message = (path.empty() ? std::string("(document)") : path) + ": " + message.substr(end + 2);
    }
  }
  // "parse error at line 1, column 3: syntax error while parsing value - invalid literal; ..."
  // reads well as it is.
  return message;
}

// Tracks the key path of the value being parsed, for errors the parser throws (it reports a
// byte position, not a key).
class KeyPathTracker {
 public:
  bool operator()(int /*depth*/, nlohmann::json::parse_event_t event, nlohmann::json& parsed) {
    using Event = nlohmann::json::parse_event_t;
    switch (event) {
      case Event::object_start: frames_.push_back({false, 0, ""}); break;
      case Event::array_start: frames_.push_back({true, 0, ""}); break;
      case Event::key:
        if (!frames_.empty() && parsed.is_string()) frames_.back().key = parsed.get<std::string>();
        break;
      case Event::object_end:
      case Event::array_end:
        if (!frames_.empty()) frames_.pop_back();
        NextElement();
        break;
      case Event::value: NextElement(); break;
    }
    return true;
  }

  std::string Path() const {
    std::string path;
    for (const Frame& frame : frames_) {
      path += "/" + (frame.array ? std::to_string(frame.index) : frame.key);
    }
    return path;
  }

 private:
  struct Frame {
    bool array;
    long index;
    std::string key;
  };
  void NextElement() {
    if (!frames_.empty() && frames_.back().array) ++frames_.back().index;
  }
  std::vector<Frame> frames_;
};

}  // namespace

nlohmann::json ParseJsonText(const std::string& text, const std::string& path) {
  KeyPathTracker tracker;
  try {
    return nlohmann::json::parse(
        text,
        [&tracker, &path](int depth, nlohmann::json::parse_event_t event, nlohmann::json& parsed) {
          // Deeper documents are refused: every later walk of the value (type errors that print
          // it, the destructor) recurses, and 100000 levels overflowed the stack.
          if (depth >= kMaxJsonDepth && (event == nlohmann::json::parse_event_t::object_start ||
                                         event == nlohmann::json::parse_event_t::array_start)) {
            std::string where = tracker.Path();
            if (where.size() > 80) where = where.substr(0, where.find('/', 60)) + "/...";
            ThrowInvalid(path + ": " + (where.empty() ? std::string() : where + ": ") +
                         "nested deeper than " + std::to_string(kMaxJsonDepth) +
                         " levels (arrays and objects)");
          }
          return tracker(depth, event, parsed);
        });
  } catch (const nlohmann::json::exception& error) {
    const std::string where = tracker.Path();
    ThrowInvalid(path + ": " + (where.empty() ? std::string() : where + ": ") +
                 "not valid JSON (" + Describe(error) + ")");
  }
}

nlohmann::json ParseJsonFile(const std::string& path) {
  return ParseJsonText(ReadTextFile(path), path);
}

void RethrowJsonError(const std::string& path, const nlohmann::json::exception& error) {
  ThrowInvalid(path + ": " + Describe(error));
}

}  // namespace aos
