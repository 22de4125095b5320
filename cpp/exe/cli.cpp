#include "cli.h"

#include <omp.h>

#include <algorithm>
#include <cmath>
#include <cstdarg>
#include <filesystem>
#include <limits>

#include <nlohmann/json.hpp>

#include "aos/image/image_io.h"
#include "aos/lightfield/formats.h"
#include "aos/util/file_util.h"
#include "aos/util/parallel.h"

namespace fs = std::filesystem;

namespace aos::cli {

void ThrowUsage(const std::string& message) { throw UsageError(message); }

CommonFlags& Common() {
  static CommonFlags common;
  return common;
}

void Say(const char* format, ...) {
  if (Common().quiet || Common().json) return;
  va_list arguments;
  va_start(arguments, format);
  std::vfprintf(stdout, format, arguments);
  va_end(arguments);
}

void Warn(const std::string& message) { std::fprintf(stderr, "warning: %s\n", message.c_str()); }
void Note(const std::string& message) { std::fprintf(stderr, "note: %s\n", message.c_str()); }

std::vector<FlagBinding>& Flags::Bindings() {
  static std::vector<FlagBinding> bindings;
  return bindings;
}

const std::vector<FlagBinding>& AllBindings() { return Flags::Bindings(); }

namespace {
// The last part of a dotted field path ("merge.num_threads" -> "num_threads").
std::string LeafOf(const std::string& path) {
  const size_t dot = path.rfind('.');
  return dot == std::string::npos ? path : path.substr(dot + 1);
}
}  // namespace

const std::vector<DeprecatedSpelling>& DeprecatedSpellings() {
  static const std::vector<DeprecatedSpelling> spellings{
      // Field-of-view and window flags named by what they describe (0.1.0).
      {"import-colmap", "--images", "--images-dir"},
      {"poses", "--fov-deg", "--frames-fov-deg"},
      {"rectify", "--fov-deg", "--rectified-fov-deg"},
      {"resolution", "--fov-deg", "--lens-fov-deg"},
      {"metrics", "--window-radius", "--ssim-window-radius"},
      // Flags named after the Options field they set.
      {"calibrate", "--square-size", "--square-size-m"},
      {"resolution", "--distance", "--distance-m"},
      {"poses", "--camera", "--camera-file"},
      {"poses", "--overlap", "--sequential-overlap"},
      {"poses", "--max-features", "--max-num-features"},
      {"poses", "--min-registered", "--min-registered-fraction"},
      {"poses", "--positions", "--positions-file"},
      {"poses", "--positions-from-exif", "--exif-positions"},
      {"import-colmap", "--min-registered", "--min-registered-fraction"},
      {"import-colmap", "--positions", "--positions-file"},
      {"import-colmap", "--positions-from-exif", "--exif-positions"},
      // Flags named after their field (issue 32): the view list.
      {"integral", "--views", "--view-indices"},
      {"stack", "--views", "--view-indices"},
      {"allinfocus", "--views", "--view-indices"},
      {"map", "--views", "--view-indices"},
      {"view", "--views", "--view-indices"},
  };
  return spellings;
}

void WarnDeprecatedSpellings(int argc, char** argv) {
  if (argc < 2) return;
  const std::string command = argv[1];
  for (int i = 2; i < argc; ++i) {
    const std::string argument = argv[i];
    for (const DeprecatedSpelling& spelling : DeprecatedSpellings()) {
      const std::string old_flag = spelling.old_flag;
      if (command == spelling.command &&
          (argument == old_flag || argument.rfind(old_flag + "=", 0) == 0)) {
        Warn(std::string(spelling.old_flag) + " is deprecated; use " + spelling.new_flag);
      }
    }
  }
}

// ---- Flags ----

Flags::Flags(CLI::App* command, std::string prefix)
    : command_(command),
      prefix_(std::move(prefix)),
      fields_(std::make_shared<std::vector<std::pair<std::string, std::string>>>()) {}

Flags Flags::Nested(const std::string& prefix) const {
  Flags nested = *this;
  nested.prefix_ = prefix_ + prefix;
  return nested;
}

Flags Flags::At(const std::string& prefix) const {
  Flags other = *this;
  other.prefix_ = prefix;
  other.scope_ = prefix;
  return other;
}

std::string Flags::NumberText(double value) {
  if (std::isinf(value)) return value > 0 ? "inf" : "-inf";
  return FormatNumber(value);
}

bool Flags::Bound(const std::string& field) const {
  // A shorthand leaves the field its own flag to get.
  for (const FlagBinding& binding : Bindings()) {
    if (binding.command == command_->get_name() && binding.field == prefix_ + field &&
        binding.source != "shorthand") {
      return true;
    }
  }
  return false;
}

std::string Flags::FlagOf(const std::string& field) { return FlagOfField(field); }

std::string Flags::Names(const std::string& flag) const {
  std::string names = flag;
  for (const DeprecatedSpelling& spelling : DeprecatedSpellings()) {
    if (command_->get_name() == spelling.command && flag == spelling.new_flag) {
      names += std::string(",") + spelling.old_flag;
    }
  }
  return names;
}

void Flags::Record(const std::string& flag, const std::string& field, const std::string& text) {
  fields_->emplace_back(prefix_ + field, flag);
  Bindings().push_back({command_->get_name(), flag, prefix_ + field, text});
}

CLI::Option* Flags::Switch(const std::string& field, bool& value, const std::string& help) {
  const std::string flag = FlagOf(field);
  CLI::Option* option = command_->add_flag(Names(flag), value, help);
  Record(flag, field, "");
  return option;
}

namespace {
std::vector<FileFlag>& FileFlags() {
  static std::vector<FileFlag> file_flags;
  return file_flags;
}
}  // namespace

const std::vector<FileFlag>& AllFileFlags() { return FileFlags(); }

const char* FileRoleName(FileRole role) {
  switch (role) {
    case FileRole::kInput: return "input";
    case FileRole::kInputFolder: return "input-folder";
    case FileRole::kOutput: return "output";
    case FileRole::kOutputFolder: return "output-folder";
  }
  return "?";
}

CLI::Option* Flags::Role(const std::string& name, FileRole role) const {
  CLI::Option* option = command_->get_option(name);  // throws for a name never declared
  FileFlags().push_back({command_->get_name(), name, role, option});
  return option;
}

void CheckFileFlags(const std::string& command) {
  struct Named {
    std::string path, flag;
    bool folder;
  };
  std::vector<Named> inputs, outputs;
  for (const FileFlag& file : AllFileFlags()) {
    if (file.command != command) continue;
    const bool is_input = file.role == FileRole::kInput || file.role == FileRole::kInputFolder;
    const bool folder = file.role == FileRole::kInputFolder || file.role == FileRole::kOutputFolder;
    for (const std::string& path : file.option->results()) {
      if (!path.empty()) (is_input ? inputs : outputs).push_back({path, file.flag, folder});
    }
  }
  std::error_code error;
  for (size_t i = 0; i < outputs.size(); ++i) {
    const Named& out = outputs[i];
    const fs::path out_path = fs::weakly_canonical(fs::absolute(out.path, error), error);
    for (size_t j = 0; j < i; ++j) {
      if (fs::weakly_canonical(fs::absolute(outputs[j].path, error), error) == out_path) {
        ThrowInvalid(out.path + ": " + out.flag + " and " + outputs[j].flag +
                     " name the same file (nothing was written)");
      }
    }
    // Nothing there yet: it is no input (the folder is the command's to check).
    if (!fs::exists(fs::symlink_status(out.path, error))) continue;
    for (const Named& in : inputs) {
      if (out.folder || fs::is_directory(out.path, error)) {
        // An output folder (or a folder given for a file): refused if it is an input folder.
        if (fs::exists(in.path, error) && fs::equivalent(out.path, in.path, error)) {
          ThrowInvalid(out.path + ": " + out.flag + ": refusing to write into an input (it is " +
                       in.flag + " " + in.path + "; nothing was written)");
        }
        continue;
      }
      try {
        CheckOutputPath(out.path, {in.path}, out.flag);
      } catch (const std::invalid_argument& refused) {
        ThrowInvalid(std::string(refused.what()) + " given as " + in.flag +
                     "; nothing was written");
      }
    }
  }
}

void Flags::Shorthand(const std::string& field, const std::string& flag) {
  fields_->emplace_back(prefix_ + field, flag);
  Bindings().push_back({command_->get_name(), flag, prefix_ + field, "", "shorthand"});
}

void Flags::AlsoSets(const std::string& field, const std::string& flag) {
  const std::string leaf = LeafOf(field);
  std::string text;
  for (const FlagBinding& binding : Bindings()) {
    if (binding.command == command_->get_name() && binding.flag == flag) text = binding.default_text;
  }
  fields_->emplace_back(prefix_ + field, flag);
  Bindings().push_back({command_->get_name(), flag, prefix_ + field, text,
                        flag == FlagOf(leaf) ? "table" : "hand"});
}

void Flags::FromTable() { Bindings().back().source = "table"; }

CLI::Option* Flags::NoDefault(CLI::Option* option) const {
  option->default_str("");
  for (FlagBinding& binding : Bindings()) {
    for (const std::string& name : option->get_lnames()) {
      if (binding.command == command_->get_name() && binding.flag == "--" + name) {
        binding.default_text.clear();
      }
    }
  }
  return option;
}

CLI::Option* Flags::AddTaking(const std::string& flag,
                              std::function<void(const std::string&)> take,
                              const std::string& help) {
  return command_->add_option_function<std::string>(
      Names(flag),
      [take = std::move(take), flag](const std::string& text) {
        try {
          take(text);
        } catch (const std::invalid_argument& error) {
          const std::string message = OneLine(error.what());
          throw CLI::ValidationError(message.find(flag) == std::string::npos
                                         ? message + " [option " + flag + "]"
                                         : message);
        }
      },
      help);
}

CLI::Option* Flags::Field(const std::string& flag, const std::string& field, int& value,
                          long long minimum, const std::string& help) {
  CLI::Option* option = Field(flag, field, value, help);
  option->check(AtLeast(minimum));
  return option;
}

CLI::Option* Flags::Threads() {
  static std::vector<std::unique_ptr<int>> spares;
  spares.push_back(std::make_unique<int>(-1));
  int* spare = spares.back().get();
  Common().num_threads[command_->get_name()] = spare;
  CLI::Option* option = command_->add_option(
      "--threads", *spare, "Worker threads (caps the process's parallel loops); -1 = all cores");
  option->default_str(DefaultText(*spare));
  return option;
}

CLI::Validator AtLeast(long long minimum) {
  return CLI::Validator(
      [minimum](std::string& text) -> std::string {
        char* end = nullptr;
        const long long value = std::strtoll(text.c_str(), &end, 10);
        if (end == text.c_str() || *end != '\0') return "'" + text + "' is not a whole number";
        if (value < minimum) {
          return "must be >= " + std::to_string(minimum) + " (got " + text + ")";
        }
        return std::string();
      },
      "INT>=" + std::to_string(minimum));
}

void Flags::Quiet() {
  command_->add_flag("-q,--quiet", Common().quiet,
                     "No progress and no report lines (errors and warnings still print)");
}

void Flags::Json() {
  command_->add_flag("--json", Common().json,
                     "Print the report as one JSON object on stdout (nothing else there)");
}

void Flags::Force() {
  command_->add_flag("--force", Common().force,
                     "Replace output files that exist (refused otherwise; folders never)");
}

void Flags::RethrowNamingFlags(const std::invalid_argument& error) const {
  const std::string message = error.what();
  const auto leaf_of = LeafOf;
  auto in_scope = [&](const std::string& path) {
    return scope_.empty() ? path.rfind("load.", 0) != 0 : path.rfind(scope_, 0) == 0;
  };
  // The flag bound to one field named in a message: its path, else its name in scope.
  // Every flag of that field (its own, then its shorthands: --focal-surface/--focal-height).
  auto flag_of = [&](const std::string& field) -> std::string {
    for (const bool by_leaf : {false, true}) {
      std::string found, path_found;
      for (const auto& [path, flag] : *fields_) {
        const bool match = by_leaf ? leaf_of(path) == field
                                   : (path == field || path == scope_ + field);
        if (!in_scope(path) || !match || (!path_found.empty() && path != path_found)) continue;
        path_found = path;
        if (("/" + found + "/").find("/" + flag + "/") == std::string::npos) {
          found += (found.empty() ? "" : "/") + flag;
        }
      }
      if (!found.empty()) return found;
    }
    return "";
  };
  // The loader asks for its own fields as "(LoadOptions::fov_deg)".
  for (const auto& [path, flag] : *fields_) {
    if (path.rfind("load.", 0) == 0 &&
        message.find("(LoadOptions::" + leaf_of(path) + ")") != std::string::npos) {
      throw UsageError(message + " [option " + flag + "]");
    }
  }
  // Options::Check() errors start with the field's path or name, or several joined by '/'
  // ("width/height: ..."): name the flag of each.
  const size_t colon = message.find(':');
  if (colon != std::string::npos && colon > 0 &&
      message.find_first_of(" \t", 0) > colon) {
    const std::string head = message.substr(0, colon);
    std::string flags;
    std::stringstream fields(head);
    std::string field;
    bool all = true;
    while (std::getline(fields, field, '/')) {
      const std::string flag = flag_of(field);
      if (flag.empty()) {
        all = false;
        continue;
      }
      if (flags.find(flag) == std::string::npos) flags += (flags.empty() ? "" : "/") + flag;
    }
    if (!flags.empty() && (all || head.find('/') != std::string::npos)) {
      throw UsageError(message + " [option " + flags + "]");
    }
  }
  throw;
}

// ---- Report ----

struct Report::Impl {
  nlohmann::ordered_json root = nlohmann::ordered_json::object();
  // Where this report writes: the top report's root, and a JSON pointer into it (a pointer to
  // an element would dangle when the parent object grows).
  nlohmann::ordered_json* top = &root;
  nlohmann::ordered_json::json_pointer at;
  nlohmann::ordered_json& Node() { return (*top)[at]; }
  std::vector<std::pair<std::string, bool>> lines;  // (text, is a result line)
  std::vector<std::pair<std::string, std::unique_ptr<Report>>> children;
  bool printed = false;
};

Report::Report(std::string command) : impl_(std::make_unique<Impl>()) {
  if (!command.empty()) impl_->root["command"] = command;
}

Report::~Report() = default;

namespace {
nlohmann::ordered_json Number(double value) {
  return std::isfinite(value) ? nlohmann::ordered_json(value) : nlohmann::ordered_json(nullptr);
}
std::string Format(const char* format, va_list arguments) {
  va_list copy;
  va_copy(copy, arguments);
  const int size = std::vsnprintf(nullptr, 0, format, copy);
  va_end(copy);
  std::string text(static_cast<size_t>(std::max(size, 0)) + 1, '\0');
  std::vsnprintf(text.data(), text.size(), format, arguments);
  text.resize(static_cast<size_t>(std::max(size, 0)));
  return text;
}
}  // namespace

void Report::Set(const std::string& key, double value) { impl_->Node()[key] = Number(value); }
void Report::Set(const std::string& key, long long value) { impl_->Node()[key] = value; }
void Report::Set(const std::string& key, bool value) { impl_->Node()[key] = value; }
void Report::Set(const std::string& key, const std::string& value) {
  impl_->Node()[key] = value;
}
void Report::Set(const std::string& key, const std::vector<std::string>& values) {
  impl_->Node()[key] = values;
}
void Report::Set(const std::string& key, const std::vector<double>& values) {
  nlohmann::ordered_json list = nlohmann::ordered_json::array();
  for (double value : values) list.push_back(Number(value));
  impl_->Node()[key] = list;
}

Report& Report::Nested(const std::string& key) {
  for (auto& [name, child] : impl_->children) {
    if (name == key) return *child;
  }
  impl_->Node()[key] = nlohmann::ordered_json::object();
  auto child = std::make_unique<Report>("");
  child->impl_->top = impl_->top;
  child->impl_->at = impl_->at / key;
  impl_->children.emplace_back(key, std::move(child));
  return *impl_->children.back().second;
}

void Report::Line(const char* format, ...) {
  va_list arguments;
  va_start(arguments, format);
  impl_->lines.emplace_back(Format(format, arguments), false);
  va_end(arguments);
}

void Report::Result(const char* format, ...) {
  va_list arguments;
  va_start(arguments, format);
  impl_->lines.emplace_back(Format(format, arguments), true);
  va_end(arguments);
}

void Report::Print() {
  if (impl_->printed) return;
  impl_->printed = true;
  if (Common().json) {
    std::fputs((impl_->root.dump(-1, ' ', false,
                                 nlohmann::ordered_json::error_handler_t::replace) +
                "\n")
                   .c_str(),
               stdout);
    return;
  }
  for (const auto& [text, result] : impl_->lines) {
    if (result || !Common().quiet) std::fputs((text + "\n").c_str(), stdout);
  }
}

// ---- Parsing ----

std::vector<double> ParseNumbers(const std::string& text, const std::string& option,
                                 size_t count) {
  std::vector<double> values;
  std::stringstream stream(text);
  std::string item;
  while (std::getline(stream, item, ',')) {
    values.push_back(AsUsage([&] { return ParseNumberText(item, option); }));
  }
  if (count > 0 && values.size() != count) {
    ThrowUsage(option + ": expected " + std::to_string(count) +
               " comma-separated numbers (got '" + text + "')");
  }
  return values;
}

Plane TextForm<Plane>::Parse(const std::string& text, const std::string& flag) {
  return ParsePlane(text, flag);
}

std::string TextForm<Plane>::Text(const Plane& plane) {
  if (plane.normal == Vec3d(0.0, 0.0, 1.0) && plane.point.x == 0.0 && plane.point.y == 0.0) {
    return FormatNumber(plane.point.z);
  }
  std::string text;
  for (double v : {plane.point.x, plane.point.y, plane.point.z, plane.normal.x, plane.normal.y,
                   plane.normal.z}) {
    text += (text.empty() ? "" : ",") + FormatNumber(v);
  }
  return text;
}

std::optional<Plane> TextForm<std::optional<Plane>>::Parse(const std::string& text,
                                                           const std::string& flag) {
  return ParsePlane(text, flag);
}

std::string TextForm<std::optional<Plane>>::Text(const std::optional<Plane>& value) {
  return value ? TextForm<Plane>::Text(*value) : "";
}

std::optional<bool> TextForm<std::optional<bool>>::Parse(const std::string& text,
                                                         const std::string& flag) {
  if (text == "true") return true;
  if (text == "false") return false;
  ThrowUsage(flag + ": expected true or false (got '" + text + "')");
}

std::string TextForm<std::optional<bool>>::Text(const std::optional<bool>& value) {
  return value ? (*value ? "true" : "false") : "";
}

std::optional<double> TextForm<std::optional<double>>::Parse(const std::string& text,
                                                             const std::string& flag) {
  return AsUsage([&] { return ParseNumberText(text, flag); });
}

std::string TextForm<std::optional<double>>::Text(const std::optional<double>& value) {
  return value ? FormatNumber(*value) : "";
}

Plane ParsePlane(const std::string& text, const std::string& option) {
  const std::vector<double> v = ParseNumbers(text, option);
  if (v.size() == 1) return Plane::AtHeight(v[0]);
  if (v.size() != 6) {
    ThrowUsage(option + ": expected a height H or six numbers PX,PY,PZ,NX,NY,NZ (got '" + text +
               "')");
  }
  return Plane{Vec3d(v[0], v[1], v[2]), Vec3d(v[3], v[4], v[5])};
}

std::vector<int> ParseViewList(const std::string& text, int view_count, const std::string& flag) {
  std::vector<int> indices;
  std::stringstream stream(text);
  std::string item;
  auto to_index = [&](const std::string& part, int fallback, int upper) {
    if (part.empty()) return fallback;
    const double value = AsUsage([&] { return ParseNumberText(part, flag); });
    if (value != std::floor(value)) ThrowUsage(flag + ": '" + part + "' is not an integer");
    if (value < 0 || value > upper) {
      ThrowUsage(flag + ": index " + part + " is outside 0.." + std::to_string(upper) +
                 " (the light field has " + std::to_string(view_count) + " views)");
    }
    return static_cast<int>(value);
  };
  while (std::getline(stream, item, ',')) {
    if (item.empty()) continue;
    const size_t colon = item.find(':');
    if (colon == std::string::npos) {
      indices.push_back(to_index(item, 0, view_count - 1));
    } else {
      const int begin = to_index(item.substr(0, colon), 0, view_count);
      const int end = to_index(item.substr(colon + 1), view_count, view_count);
      if (begin > end) ThrowUsage(flag + ": range '" + item + "' runs backwards");
      for (int i = begin; i < end; ++i) indices.push_back(i);
    }
  }
  if (indices.empty()) {
    ThrowUsage(flag + ": the selection '" + text + "' is empty (view selection is empty)");
  }
  return indices;
}

// ---- Outputs ----

void RefuseExisting(const std::string& path, const std::string& what) {
  std::error_code error;
  const fs::file_status status = fs::symlink_status(path, error);
  if (error || !fs::exists(status)) return;
  if (fs::is_directory(fs::status(path, error))) {
    ThrowInvalid(path + ": " + what + " is a folder; give a file name");
  }
  if (!Common().force) {
    ThrowInvalid(path + ": " + what + " exists; give --force to replace it (nothing was written)");
  }
}

void AddImageOutputFlags(Flags& flags, ImageOutputOptions& out) {
  CLI::App* command = flags.command();
  command->add_option("--sample-type", out.sample_type,
                      "Sample type of written images: auto, uint8, uint16, float32")
      ->default_str(out.sample_type);
  command->add_option("--range", out.range,
                      "Value range mapped onto 0..max code for 8/16-bit outputs: 'views' (the "
                      "views' native range: 0..255 for 8-bit, 0..65535 for 16-bit, 0..1 for "
                      "float), 'minmax' (the covered pixels' min..max), or LO,HI")
      ->default_str(out.range);
}

void CheckImageOutput(const ImageOutputOptions& out, const std::string& path) {
  if (out.range != "views" && out.range != "minmax") {
    const std::vector<double> range = ParseNumbers(out.range, "--range", 2);
    if (!(range[1] > range[0])) {
      ThrowUsage("--range: expected LO,HI with HI > LO (got '" + out.range + "')");
    }
  }
  WriteImageOptions write;
  write.sample_type = AsUsage([&] { return ParseSampleType(out.sample_type); });
  AsUsage([&] { return ResolveSampleType(path, Image(1, 1, 1, PixelType::kF32), write); });
}

CLI::Option* AddGreyFlag(Flags& loader, LoadOptions& load) {
  return loader.Field(load, "grey");
}

}  // namespace aos::cli
