#pragma once
// The CLI's shared machinery: the command table's types, flags bound to Options fields, the
// flags every command has, the report a command prints, and output checks.
//
// A command is one function `CommandRunner DefineX(CLI::App* command)` that declares its flags on
// `command` (through a Flags binder) and returns the function that runs it once parsed; the
// table in aos_render.cpp lists each command once (name, one-line help, Define function), the
// way COLMAP's exe/colmap.cc does. Each area's commands live in their own file.
//
// A flag is a field: Flags::Field(options, name) binds the flag of a field-table row
// (util/option_fields.h: `--kebab-name`, or the row's own flag) to that field, with the row's
// help and range and the struct's default (read from the field itself, never re-typed); a type
// beyond numbers, text, enums and switches is read by its TextForm, and a value resolved once
// the light field is loaded by a per-row reader. Flags::Remaining gives every other row its
// flag. Other spellings of a field (--focal-height H for focal_surface) are shorthands beside
// its own flag (Flags::Shorthand). Every binding is recorded, so that an error from
// Options::Check() ("fov_deg: ...") names the flags that set the field, and `aos-render flags`
// lists every binding with how it was declared (tools/vocabulary.py reads it).
//
// A flag that names a file is declared with its role (Flags::Input, InputFolder, Output,
// OutputFolder, by the option's name): before a command runs, main() refuses every output that
// is the same file as an input or a file of an input folder (links resolved), and two outputs
// naming one file, --force or not (CheckFileFlags); `aos-render flags --files` lists the roles
// (tests/python/test_cli_table.py runs every output x input pair of every command from it).
//
// Exit codes: 0 success, 1 bad input or failure, 2 bad command line (UsageError), 128 + the
// signal when interrupted: 130 SIGINT (Ctrl-C), 143 SIGTERM, 129 SIGHUP (progress_bar.h).
#include <cmath>
#include <cstdio>
#include <limits>
#include <functional>
#include <initializer_list>
#include <map>
#include <memory>
#include <optional>
#include <sstream>
#include <stdexcept>
#include <string>
#include <type_traits>
#include <utility>
#include <vector>

#include <CLI/CLI.hpp>

#include "aos/geometry/rigid.h"
#include "aos/image/image.h"
#include "aos/lightfield/formats.h"
#include "aos/util/error.h"
#include "aos/util/option_fields.h"

namespace aos::cli {

// The command table's types.
using CommandRunner = std::function<int()>;
using DefineCommand = CommandRunner (*)(CLI::App* command);
struct CommandEntry {
  const char* name;
  const char* help;
  DefineCommand define;
};

// A mistake on the command line found while interpreting the values (out of range, malformed
// lists, unknown names): exit code 2, like the parser's own errors.
class UsageError : public std::invalid_argument {
 public:
  explicit UsageError(const std::string& message) : std::invalid_argument(OneLine(message)) {}
};

[[noreturn]] void ThrowUsage(const std::string& message);

// Runs `interpret` (which reads a flag's value) and turns its std::invalid_argument into a
// UsageError.
template <class Interpret>
auto AsUsage(Interpret&& interpret) -> decltype(interpret()) {
  try {
    return interpret();
  } catch (const UsageError&) {
    throw;
  } catch (const std::invalid_argument& error) {
    throw UsageError(error.what());
  }
}

// The flags every command has (-q, --json, --threads; --force where it writes files), set by
// the parser for the one command that runs.
struct CommonFlags {
  bool quiet = false;  // -q: no progress, no report lines (errors and warnings still print)
  bool json = false;   // --json: the report as one JSON object on stdout, nothing else there
  bool force = false;  // --force: replace output files that exist (refused otherwise)
  // Each command's --threads value (its Options field, or a spare): after parsing, the
  // running command's value also caps the process's OpenMP workers.
  std::map<std::string, int*> num_threads;
};
CommonFlags& Common();

// printf to stdout unless -q or --json.
__attribute__((format(printf, 1, 2))) void Say(const char* format, ...);
// "warning: ..." / "note: ..." on stderr (even with -q: warnings are never silenced).
void Warn(const std::string& message);
void Note(const std::string& message);

// One flag bound to an Options field.
struct FlagBinding {
  std::string command;  // e.g. "allinfocus"
  std::string flag;     // e.g. "--agreement" (the new spelling)
  std::string field;    // dotted path in the command's Options struct, e.g. "merge.robust.agreement"
  std::string default_text;  // as --help prints it ("" when it prints none)
  // How the flag was declared: "table" (from the field's row: flag, help, default and range,
  // Flags::Field(options, name) and Remaining), "shorthand" (another spelling of a field that
  // has its table flag too, Flags::Shorthand: --focal-height H for focal_surface), or "hand"
  // (flag and help typed in the command: a struct without a table).
  std::string source = "hand";
};
// Every binding of every command, in declaration order (for `aos-render flags`).
const std::vector<FlagBinding>& AllBindings();

// What a flag's value names (see the header comment).
enum class FileRole { kInput, kInputFolder, kOutput, kOutputFolder };
// "input", "input-folder", "output", "output-folder".
const char* FileRoleName(FileRole role);
struct FileFlag {
  std::string command;  // e.g. "integral"
  std::string flag;     // the option's name as --help prints it: "--mask", "lightfield"
  FileRole role;
  const CLI::Option* option;  // its values once parsed
};
// Every file flag of every command, in declaration order.
const std::vector<FileFlag>& AllFileFlags();
// Throws std::invalid_argument naming both flags if an output flag of `command` names an
// existing file that is the same file as an input flag's (or a file of an input folder, or an
// input folder itself), or if two output flags name the same path. Run by main() after parsing,
// before the command; the frames a light field names are checked by the command once loaded.
void CheckFileFlags(const std::string& command);

// Refuses whole numbers below `minimum` with a plain message (the parser then exits with 2).
CLI::Validator AtLeast(long long minimum);

// Old spellings kept for one release (CHANGELOG.md): (command, new flag) -> old flag. The binder
// adds the old spelling as an alias; WarnDeprecatedSpellings prints a warning naming the new one.
struct DeprecatedSpelling {
  const char* command;
  const char* old_flag;
  const char* new_flag;
};
const std::vector<DeprecatedSpelling>& DeprecatedSpellings();
void WarnDeprecatedSpellings(int argc, char** argv);

// Default text of a value as --help prints it.
template <class T>
std::string DefaultText(const T& value) {
  if constexpr (std::is_same_v<T, bool>) {
    return value ? "true" : "false";
  } else if constexpr (std::is_floating_point_v<T>) {
    return FormatNumber(static_cast<double>(value));
  } else if constexpr (std::is_arithmetic_v<T>) {
    return std::to_string(value);
  } else {
    return std::string(value);
  }
}

// A field type's spelling on the command line, beyond numbers, text, enums and switches (which
// Flags reads itself): `Parse(text, flag)` (throws std::invalid_argument), `Text(value)` (the
// default as --help prints it; "" for none) and `kSpelling` (the help's hint). A table row of
// such a type gets its flag like any other (Flags::Field, Remaining).
template <class T>
struct TextForm;
template <class T, class = void>
struct HasTextForm : std::false_type {};
template <class T>
struct HasTextForm<T, std::void_t<decltype(TextForm<T>::kSpelling)>> : std::true_type {};
template <class T>
inline constexpr bool kHasTextForm = HasTextForm<T>::value;

// A plane: "H" (the horizontal plane z = H) or "PX,PY,PZ,NX,NY,NZ"; printed as H when it is
// the horizontal plane through (0, 0, H).
template <>
struct TextForm<Plane> {
  static constexpr const char* kSpelling = "a height H or PX,PY,PZ,NX,NY,NZ";
  static Plane Parse(const std::string& text, const std::string& flag);
  static std::string Text(const Plane& value);
};
// The same, unset by default.
template <>
struct TextForm<std::optional<Plane>> {
  static constexpr const char* kSpelling = "H or PX,PY,PZ,NX,NY,NZ";
  static std::optional<Plane> Parse(const std::string& text, const std::string& flag);
  static std::string Text(const std::optional<Plane>& value);
};
// N numbers "A,B,..." (a centre X,Y).
template <size_t N>
struct TextForm<std::array<double, N>> {
  static constexpr const char* kSpelling = "comma-separated numbers";
  static std::array<double, N> Parse(const std::string& text, const std::string& flag);
  static std::string Text(const std::array<double, N>& value) {
    std::string text;
    for (double v : value) text += (text.empty() ? "" : ",") + FormatNumber(v);
    return text;
  }
};
// A yes/no that may be left unset (the program decides): "true" or "false".
template <>
struct TextForm<std::optional<bool>> {
  static constexpr const char* kSpelling = "true or false; unset: decided at run time";
  static std::optional<bool> Parse(const std::string& text, const std::string& flag);
  static std::string Text(const std::optional<bool>& value);
};

// A number that may be left unset (the program finds it: a take-off height sampled from a DEM).
template <>
struct TextForm<std::optional<double>> {
  static constexpr const char* kSpelling = "a number; unset by default";
  static std::optional<double> Parse(const std::string& text, const std::string& flag);
  static std::string Text(const std::optional<double>& value);
};

// Binds one command's flags to the fields of its Options struct (see the header comment).
class Flags {
 public:
  Flags(CLI::App* command, std::string prefix = "");
  // The same binder for a nested struct: fields are recorded as `prefix + field`.
  Flags Nested(const std::string& prefix) const;
  // The same binder for a struct outside the command's Options (e.g. "load." for LoadOptions);
  // its RethrowNamingFlags names only flags bound under that prefix (a loader's "fov_deg: ..."
  // is --frames-fov-deg's, not the virtual camera's --fov-deg).
  Flags At(const std::string& prefix) const;

  // --kebab-case(field) -> `value`, with the field's current value as the printed default.
  template <class T>
  CLI::Option* Field(const std::string& field, T& value, const std::string& help) {
    return Field(FlagOf(field), field, value, help);
  }
  // A flag spelled differently from its field (e.g. --threads for num_threads).
  template <class T>
  CLI::Option* Field(const std::string& flag, const std::string& field, T& value,
                     const std::string& help) {
    CLI::Option* option = command_->add_option(Names(flag), value, help);
    const std::string text = DefaultText(value);
    option->default_str(text);
    Record(flag, field, text);
    return option;
  }
  // The flag of the field `name` of `options`' table (util/option_fields.h): --kebab-name bound
  // to that field, its help the table's, its default the field's value. A number outside the
  // table's range is refused by the parser (exit 2) naming the flag and the range; a double
  // takes "inf" where the range allows it; an enum takes its value names; a bool is a switch.
  template <class Options>
  CLI::Option* Field(Options& options, const std::string& name) {
    CLI::Option* option = nullptr;
    Options::Fields([&](const auto& spec) {
      if (name == spec.name) {
        option = TableField(options.*(spec.member), spec);
        FromTable();
      }
    });
    if (option == nullptr) throw std::logic_error("Flags::Field: no field " + name + " in the table");
    return option;
  }
  // The flag of the field `name` of `options`' table (its row's flag, help and default, as
  // above), whose text goes to `take` instead of the type's own reading: a value spelled beyond
  // its type and resolved once the light field is loaded (a view's index or name, a height or
  // a terrain file). `take` may throw std::invalid_argument (exit 2, naming the flag).
  template <class Options>
  CLI::Option* Field(Options& options, const std::string& name,
                     std::function<void(const std::string&)> take,
                     const std::string& more_help = "") {
    CLI::Option* option = nullptr;
    Options::Fields([&](const auto& spec) {
      if (name != spec.name) return;
      const std::string flag = FlagOf(spec);
      option = AddTaking(flag, std::move(take), spec.help + more_help);
      const std::string text = TextOf(options.*(spec.member));
      if (!text.empty()) option->default_str(text);
      Record(flag, name, text);
      FromTable();
    });
    if (option == nullptr) throw std::logic_error("Flags::Field: no field " + name + " in the table");
    return option;
  }
  // Another spelling of `field`, which has its table flag too (declared by the caller on
  // command(): --focal-height H for focal_surface, --look-at for cam_from_world); errors about
  // the field then name it as well, and `aos-render flags` lists it as a shorthand.
  void Shorthand(const std::string& field, const std::string& flag);
  // A shorthand declared here: `flag` whose text `parse` turns into the field's value.
  template <class T, class Parse>
  CLI::Option* Shorthand(const std::string& field, const std::string& flag, T& value, Parse parse,
                         const std::string& help) {
    CLI::Option* option = Parsed(flag, field, value, parse, "", help);
    Bindings().back().source = "shorthand";
    return option;
  }
  // `option` (a flag of this command) with no default in --help or `aos-render flags`: a field
  // the command fills from others when the flag is not given (camera's fy = fx).
  CLI::Option* NoDefault(CLI::Option* option) const;
  // The same flag for a second field of this name in the command (allinfocus's --threads sets
  // the stack's and the merge's num_threads): recorded as that field's table flag.
  void AlsoSets(const std::string& field, const std::string& flag);
  // Flags for every field of `options`' table that has none yet on this binder's path and is
  // not in `not_on_the_cli` (each with its reason in tools/vocabulary.py NOT_ON_THE_CLI), as
  // Field(options, name) binds them. Nested Options fields are skipped (their binder calls
  // this for them). Call last in a command's Define, after the fields bound by hand: a field
  // added to a table then gets its flag on every command that fills that struct.
  template <class Options>
  void Remaining(Options& options, std::initializer_list<const char*> not_on_the_cli = {}) {
    std::vector<std::string> names;
    Options::Fields([&](const auto& spec) {
      using T = typename std::decay_t<decltype(spec)>::Type;
      if constexpr (!kHasFieldTable<T>) {
        const std::string name = spec.name;
        for (const char* excluded : not_on_the_cli) {
          if (name == excluded) return;
        }
        if (!Bound(name)) names.push_back(name);
      }
    });
    for (const std::string& name : names) Field(options, name);
  }
  // A field whose "not given" means something the help states (no default printed).
  template <class T>
  CLI::Option* Optional(const std::string& flag, const std::string& field, T& value,
                        const std::string& help) {
    CLI::Option* option = command_->add_option(Names(flag), value, help);
    Record(flag, field, "");
    return option;
  }
  // A whole-number field with a lower bound (the parser refuses less, exit code 2).
  CLI::Option* Field(const std::string& flag, const std::string& field, int& value,
                     long long minimum, const std::string& help);
  // A switch (a bool field, default false).
  CLI::Option* Switch(const std::string& field, bool& value, const std::string& help);
  // A field given as text and converted by `parse` (planes, enums, "inf"), which may throw
  // std::invalid_argument; `default_text` is the field's default in the same spelling.
  template <class T, class Parse>
  CLI::Option* Parsed(const std::string& flag, const std::string& field, T& value, Parse parse,
                      const std::string& default_text, const std::string& help) {
    // Errors name the flag, as range errors do (AddTaking).
    CLI::Option* option =
        AddTaking(flag, [&value, parse](const std::string& text) { value = parse(text); }, help);
    if (!default_text.empty()) option->default_str(default_text);
    Record(flag, field, default_text);
    return option;
  }
  // Declares the role of the option named `name` (a flag "--mask" or a positional "lightfield";
  // it must exist) in the command's file checks. Returns the option.
  CLI::Option* Input(const std::string& name) const { return Role(name, FileRole::kInput); }
  CLI::Option* InputFolder(const std::string& name) const {
    return Role(name, FileRole::kInputFolder);
  }
  CLI::Option* Output(const std::string& name) const { return Role(name, FileRole::kOutput); }
  CLI::Option* OutputFolder(const std::string& name) const {
    return Role(name, FileRole::kOutputFolder);
  }


  // --threads bound to `options.num_threads` through its table row (help, default, range, as
  // Field(options, "num_threads")), the help followed by what the CLI adds: the count also caps
  // the process's parallel loops, so every stage of the command reads it.
  template <class Options>
  CLI::Option* Threads(Options& options) {
    Common().num_threads[command_->get_name()] = &options.num_threads;
    CLI::Option* option = Field(options, "num_threads");
    option->description(option->get_description() +
                        " The count also caps the process's parallel loops (every stage).");
    return option;
  }
  // --threads for a command whose Options have no thread count: caps the process's workers.
  CLI::Option* Threads();
  // -q and --json (every command has them; Define functions get them from the table).
  void Quiet();
  void Json();
  // --force, on commands that write files.
  void Force();

  // Rethrows an Options::Check() error ("field: ...", also "(LoadOptions::field)") as a
  // UsageError naming the flag bound to that field; other errors unchanged.
  [[noreturn]] void RethrowNamingFlags(const std::invalid_argument& error) const;
  // Runs `run` and names flags in its std::invalid_argument.
  template <class Run>
  auto NamingFlags(Run&& run) const -> decltype(run()) {
    try {
      return run();
    } catch (const UsageError&) {
      throw;
    } catch (const std::invalid_argument& error) {
      RethrowNamingFlags(error);
    }
  }

  CLI::App* command() const { return command_; }
  // Every binding of every command (AllBindings), to record in.
  static std::vector<FlagBinding>& Bindings();

 private:
  template <class T, class Spec>
  CLI::Option* TableField(T& value, const Spec& spec) {
    const std::string name = spec.name;
    const std::string flag = FlagOf(spec);
    if constexpr (std::is_same_v<T, bool>) {
      // A switch; one that defaults to true prints it and is turned off as --flag=false.
      CLI::Option* option = command_->add_flag(Names(flag), value, spec.help);
      if (value) option->default_str("true");
      Record(flag, name, value ? "true" : "");
      return option;
    } else if constexpr (kHasTextForm<T>) {
      return Parsed(
          flag, name, value,
          [flag](const std::string& text) { return TextForm<T>::Parse(text, flag); },
          TextForm<T>::Text(value), std::string(spec.help) + " (" + TextForm<T>::kSpelling + ")");
    } else if constexpr (std::is_enum_v<T>) {
      return Parsed(
          flag, name, value, [flag](const std::string& text) { return EnumFromName<T>(text, flag); },
          EnumName(value), std::string(spec.help) + " (" + EnumChoices<T>() + ")");
    } else if constexpr (std::is_arithmetic_v<T>) {
      const Range range = spec.range;
      return Parsed(
          flag, name, value,
                 [name, flag, range](const std::string& text) {
            return NumberInRange<T>(text, name, flag, range);
          },
                 NumberText(static_cast<double>(value)), spec.help)
          ->type_name(std::is_integral_v<T> ? "INT" : "FLOAT");
    } else if constexpr (std::is_same_v<T, std::vector<double>>) {  // numbers as arguments
      CLI::Option* option = command_->add_option(Names(flag), value, spec.help);
      Record(flag, name, "");
      return option;
    } else if constexpr (std::is_same_v<T, std::string>) {
      CLI::Option* option = Field(flag, name, value, spec.help);
      if (spec.range.choices != nullptr) {  // refused while parsing, naming field and flag
        const Range range = spec.range;
        option->check(
            [range, name, flag](const std::string& text) -> std::string {
              return range.ContainsText(text) ? std::string()
                                              : name + ": must be " + range.Text() + ", got '" +
                                                    text + "' [option " + flag + "]";
            },
            "");  // the help lists the choices
      }
      return option;
    } else {
      throw std::logic_error("Flags::Field: " + name + " has no flag of its own type");
    }
  }
  // A number as --help prints a default ("inf" for infinity).
  static std::string NumberText(double value);
  // `text` as a T in `range` ("inf" and "infinity" too for a double); throws
  // std::invalid_argument "field: ... [option --flag]" otherwise, as Check() errors read.
  template <class T>
  static T NumberInRange(const std::string& text, const std::string& field,
                         const std::string& flag, const Range& range) {
    const std::string option = " [option " + flag + "]";
    double number = 0.0;
    if (std::is_floating_point_v<T> && (text == "inf" || text == "infinity")) {
      number = std::numeric_limits<double>::infinity();
    } else {
      try {
        number = ParseNumberText(text, field);
      } catch (const std::invalid_argument& error) {
        ThrowInvalid(error.what() + option);
      }
    }
    if constexpr (std::is_integral_v<T>) {
      // The bounds as doubles: max + 1 is exact (2^31) or rounds to 2^63, both excluded.
      const double lowest = static_cast<double>(std::numeric_limits<T>::min());
      const double beyond = static_cast<double>(std::numeric_limits<T>::max()) + 1.0;
      if (number != std::floor(number) || !(number >= lowest && number < beyond)) {
        ThrowInvalid(field + ": expected a whole number, got " + text + option);
      }
    }
    if (!range.Contains(number)) {
      ThrowInvalid(field + ": must be " + range.Text() + ", got " + text + option);
    }
    return static_cast<T>(number);
  }
  // Whether `field` (on this binder's path) has a flag already.
  bool Bound(const std::string& field) const;
  // --kebab-name; num_threads is --threads on every command (the one spelling rule).
  static std::string FlagOf(const std::string& field);
  // A row's flag: its own (OptionFieldSpec::flag) or FlagOf(name).
  template <class Spec>
  static std::string FlagOf(const Spec& spec) {
    return FlagOfField(spec.name, spec.flag);
  }
  // A value's text as --help prints a default ("" for none).
  template <class T>
  static std::string TextOf(const T& value) {
    if constexpr (std::is_same_v<T, bool>) {
      return "";
    } else if constexpr (std::is_enum_v<T>) {
      return EnumName(value);
    } else if constexpr (std::is_arithmetic_v<T>) {
      return NumberText(static_cast<double>(value));
    } else if constexpr (std::is_same_v<T, std::string>) {
      return value;
    } else if constexpr (kHasTextForm<T>) {
      return TextForm<T>::Text(value);
    } else {
      return "";
    }
  }
  CLI::Option* AddTaking(const std::string& flag, std::function<void(const std::string&)> take,
                         const std::string& help);
  // Marks the last binding recorded as the table's (FlagBinding::source).
  static void FromTable();
  std::string Names(const std::string& flag) const;
  void Record(const std::string& flag, const std::string& field, const std::string& text);
  CLI::Option* Role(const std::string& name, FileRole role) const;

  CLI::App* command_;
  std::string prefix_;
  std::string scope_;  // set by At(): only bindings under it name flags
  // field path or leaf name -> flag(s), this command only (shared by Nested binders).
  std::shared_ptr<std::vector<std::pair<std::string, std::string>>> fields_;
};

// What a command reports: with --json one JSON object on stdout (nothing else there), else
// text lines (unless -q). Keys are added in order; values are numbers, strings or lists.
class Report {
 public:
  explicit Report(std::string command);
  ~Report();
  void Set(const std::string& key, double value);
  void Set(const std::string& key, long long value);
  void Set(const std::string& key, int value) { Set(key, static_cast<long long>(value)); }
  void Set(const std::string& key, size_t value) { Set(key, static_cast<long long>(value)); }
  void Set(const std::string& key, bool value);
  void Set(const std::string& key, const std::string& value);
  void Set(const std::string& key, const char* value) { Set(key, std::string(value)); }
  void Set(const std::string& key, const std::vector<std::string>& values);
  void Set(const std::string& key, const std::vector<double>& values);
  // A nested object for values, e.g. report.Nested("single_view").Set(...) (its text lines are
  // not printed: add those to the top report).
  Report& Nested(const std::string& key);
  // A text line for the plain report (printed by Print unless --json or -q). Lines that are
  // the command's result (metrics, resolution) print even with -q: pass result = true.
  __attribute__((format(printf, 2, 3))) void Line(const char* format, ...);
  __attribute__((format(printf, 2, 3))) void Result(const char* format, ...);
  // Prints the report (once).
  void Print();

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

// "a,b,c" -> numbers (a UsageError naming `option` for a bad one); `count` > 0 checks the count.
std::vector<double> ParseNumbers(const std::string& text, const std::string& option,
                                 size_t count = 0);
// "H" (the horizontal plane z = H) or "PX,PY,PZ,NX,NY,NZ".
Plane ParsePlane(const std::string& text, const std::string& option);
// "0:10,15,20:30" -> indices checked against [0, view_count); errors name `flag`.
std::vector<int> ParseViewList(const std::string& text, int view_count,
                               const std::string& flag = "--view-indices");

// Refuses an existing `path` (a file, a folder or a link) unless --force (files only: folders
// are never replaced).
void RefuseExisting(const std::string& path, const std::string& what);

// --grey bound to LoadOptions::grey through `loader` (the binder At("load.")): the one spelling
// on every command that loads a light field (frames become Rec. 601 luminance at load).
CLI::Option* AddGreyFlag(Flags& loader, LoadOptions& load);

// Sample type and value range of written images (--sample-type, --range).
struct ImageOutputOptions {
  std::string sample_type = "auto";  // auto, uint8, uint16, float32
  std::string range = "views";       // views, minmax, or LO,HI
};
void AddImageOutputFlags(Flags& flags, ImageOutputOptions& out);
// Checks --sample-type/--range and that `path` can hold the samples; throws a UsageError.
void CheckImageOutput(const ImageOutputOptions& out, const std::string& path);

template <size_t N>
std::array<double, N> TextForm<std::array<double, N>>::Parse(const std::string& text,
                                                             const std::string& flag) {
  const std::vector<double> v = ParseNumbers(text, flag, N);
  std::array<double, N> values{};
  std::copy(v.begin(), v.end(), values.begin());
  return values;
}

}  // namespace aos::cli
