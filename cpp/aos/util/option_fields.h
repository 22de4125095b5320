#pragma once
// Field tables: every field of an Options struct listed once (name, member, unit, range, help),
// the way COLMAP's option manager registers each option once for its CLI and its project file.
//
// Contract
// - An Options struct with a table declares, after its members,
//     template <class Visit> static void Fields(Visit&& field) {
//       field(OptionField("agreement", &SurfaceIntegralOptions::agreement, "",
//                         Range::OpenClosed(0.0, 1.0), "Half-width of the agreement band ..."));
//       ...
//     }
//   calling `field` once per member, in declaration order. The default of a field is the
//   member's initializer: nothing else states it.
// - From the table come, without a second list: the Python class of a bound struct
//   (cpp/python/bindings.h: OptionsClass::Table: properties, keyword constructor, repr, ==,
//   pickle, to_json/from_json, docstrings from `help`, and the class attribute `_field_table`);
//   the JSON form (lightfield/options_json.h: the `view` and `map --workers` hand-off); the
//   range part of Check() (CheckFieldRanges below); the CLI flags (cpp/exe/cli.h:
//   Flags::Field(options, name) and Flags::Remaining: --kebab-name, help, default and range);
//   and, through tools/options.py, the Options classes of _core.pyi and the keyword TypedDicts
//   of _keywords.py (tests/python/test_options.py fails when they are stale). docs/options.md.
// - A block of fields several structs share is a base struct with its own table, which the
//   derived tables include (render/aperture.h: ApertureOptions).
// - A row's CLI flag is --kebab-name unless the row says otherwise (`.Flag("frames-fov-deg")`,
//   where one command would otherwise have two flags of one name); the CLI's text form of the
//   field's type (cpp/exe/cli.h: TextForm) reads the value.
// - `range` is checked by CheckFieldRanges for number fields (int, double; bool excluded): a
//   value outside it (NaN included) throws std::invalid_argument "name: must be <range>, got v".
//   A text field's range may list its choices (Range::OneOf("scan|grid|circles")): another
//   value throws "name: must be one of scan, grid or circles, got 'x'"; Python types it as a
//   Literal and the CLI refuses another value while parsing.
//   Conditions between fields stay in the struct's Check().
// - Enum fields name their values through EnumNames<E> (specialised beside the enum): the JSON,
//   the CLI and Python use those names.
#include <cmath>
#include <cstddef>
#include <limits>
#include <string>
#include <type_traits>
#include <utility>
#include <vector>

#include "aos/util/error.h"

namespace aos {

// The values a number field may take: an interval, and optionally one value outside it with a
// meaning of its own (0 = "the pose view's", -1 = "all cores"), stated in the field's help.
struct Range {
  double lo = -std::numeric_limits<double>::infinity();
  double hi = std::numeric_limits<double>::infinity();
  bool lo_open = false;
  bool hi_open = false;
  bool has_special = false;
  double special = 0.0;
  // For a text field: the values it takes, separated by '|' ("circle|sector|line"); null = any.
  const char* choices = nullptr;

  // Any value (for a double: any finite value or +-infinity; NaN is refused).
  static constexpr Range Any() { return Range{}; }
  static constexpr Range Closed(double lo, double hi) { return Range{lo, hi, false, false}; }
  static constexpr Range Open(double lo, double hi) { return Range{lo, hi, true, true}; }
  static constexpr Range ClosedOpen(double lo, double hi) { return Range{lo, hi, false, true}; }
  static constexpr Range OpenClosed(double lo, double hi) { return Range{lo, hi, true, false}; }
  static constexpr Range AtLeast(double lo) {
    return Range{lo, std::numeric_limits<double>::infinity(), false, false};
  }
  static constexpr Range Above(double lo) {
    return Range{lo, std::numeric_limits<double>::infinity(), true, false};
  }
  // Finite values only.
  static constexpr Range Finite() {
    return Range{-std::numeric_limits<double>::max(), std::numeric_limits<double>::max()};
  }
  // Finite values >= lo (> lo with `open`).
  static constexpr Range FiniteAtLeast(double lo, bool open = false) {
    return Range{lo, std::numeric_limits<double>::max(), open, false};
  }
  // A text field taking one of `choices`, separated by '|' ("scan|grid|circles").
  static constexpr Range OneOf(const char* choices) {
    Range range;
    range.choices = choices;
    return range;
  }
  // This range and also `value`.
  constexpr Range Or(double value) const {
    Range range = *this;
    range.has_special = true;
    range.special = value;
    return range;
  }

  bool Contains(double value) const {
    if (has_special && value == special) return true;
    if (std::isnan(value)) return false;
    const bool above = lo_open ? value > lo : value >= lo;
    const bool below = hi_open ? value < hi : value <= hi;
    return above && below;
  }
  bool IsAny() const {
    return choices == nullptr && !has_special && std::isinf(lo) && lo < 0 && std::isinf(hi);
  }
  // Whether a text field's value is one of the choices (true without choices).
  bool ContainsText(const std::string& value) const;
  // The choices, in order (empty without choices).
  std::vector<std::string> Choices() const;
  // "in [0, 90)", "> 0", ">= 16 or 0", "a number" (for Any), "one of scan, grid or circles".
  std::string Text() const;
};

// One row of a field table (see the contract).
template <class Options, class T>
struct OptionFieldSpec {
  using Struct = Options;
  using Type = T;
  const char* name;
  T Options::*member;
  const char* unit;  // "m", "deg", "px", "MiB", "" (none)
  Range range;
  const char* help;
  // The CLI flag without "--" where it is not the name's kebab case (nullptr: --kebab-name).
  // Only where one command has two fields of this name (a loader's fov_deg beside the virtual
  // camera's: "frames-fov-deg"), or the flag names what the field means in that command.
  const char* flag = nullptr;

  // This row with the CLI flag `flag_name` (see `flag`).
  constexpr OptionFieldSpec Flag(const char* flag_name) const {
    OptionFieldSpec row = *this;
    row.flag = flag_name;
    return row;
  }
};

// The CLI flag of a row named `name` whose own flag is `flag` (nullptr: none): "--" + flag, or
// "--kebab-name"; num_threads is "--threads" everywhere (the one spelling rule).
std::string FlagOfField(const std::string& name, const char* flag = nullptr);

template <class Options, class T>
constexpr OptionFieldSpec<Options, T> OptionField(const char* name, T Options::*member,
                                                  const char* unit, Range range,
                                                  const char* help) {
  return {name, member, unit, range, help, nullptr};
}

// The names of an enum's values, specialised beside the enum:
//   template <> struct EnumNames<MergeMethod> {
//     static constexpr std::pair<MergeMethod, const char*> kValues[] = {...};
//   };
template <class E>
struct EnumNames;

// The name of `value` ("?" for a value not listed).
template <class E>
const char* EnumName(E value) {
  for (const auto& [candidate, name] : EnumNames<E>::kValues) {
    if (candidate == value) return name;
  }
  return "?";
}
// "a, b, c": every name.
template <class E>
std::string EnumChoices() {
  std::string text;
  for (const auto& entry : EnumNames<E>::kValues) {
    text += (text.empty() ? "" : ", ") + std::string(entry.second);
  }
  return text;
}
// The value named `name`; throws std::invalid_argument "field: unknown value 'x' (one of ...)".
template <class E>
E EnumFromName(const std::string& name, const std::string& field) {
  for (const auto& [value, candidate] : EnumNames<E>::kValues) {
    if (name == candidate) return value;
  }
  ThrowInvalid(field + ": unknown value '" + name + "' (one of " + EnumChoices<E>() + ")");
}

namespace detail {
struct AnyFieldVisitor {
  template <class O, class T>
  void operator()(const OptionFieldSpec<O, T>&) const {}
};
}  // namespace detail

// Whether T declares a field table.
template <class T, class = void>
struct HasFieldTable : std::false_type {};
template <class T>
struct HasFieldTable<T, std::void_t<decltype(T::Fields(std::declval<detail::AnyFieldVisitor&>()))>>
    : std::true_type {};
template <class T>
inline constexpr bool kHasFieldTable = HasFieldTable<T>::value;

// Whether T is an enum with EnumNames.
template <class T, class = void>
struct HasEnumNames : std::false_type {};
template <class T>
struct HasEnumNames<T, std::void_t<decltype(EnumNames<T>::kValues)>> : std::true_type {};

// Number of fields in T's table.
template <class Options>
size_t FieldCount() {
  size_t count = 0;
  Options::Fields([&count](const auto&) { ++count; });
  return count;
}

// The text fields' choices only (part of CheckFieldRanges), for a Check() that tests them before
// conditions that read them.
template <class Options>
void CheckFieldChoices(const Options& options) {
  Options::Fields([&options](const auto& field) {
    using T = typename std::decay_t<decltype(field)>::Type;
    if constexpr (std::is_same_v<T, std::string>) {
      const std::string& value = options.*(field.member);
      if (!field.range.ContainsText(value)) {
        ThrowInvalid(std::string(field.name) + ": must be " + field.range.Text() + ", got '" +
                     value + "'");
      }
    }
  });
}

// Checks every number field of `options` against its range, and every text field against its
// choices (see the contract).
template <class Options>
void CheckFieldRanges(const Options& options) {
  Options::Fields([&options](const auto& field) {
    using T = typename std::decay_t<decltype(field)>::Type;
    if constexpr (std::is_arithmetic_v<T> && !std::is_same_v<T, bool>) {
      const double value = static_cast<double>(options.*(field.member));
      if (!field.range.Contains(value)) {
        ThrowInvalid(std::string(field.name) + ": must be " + field.range.Text() + ", got " +
                     FormatNumber(value));
      }
    }
  });
  CheckFieldChoices(options);
}

}  // namespace aos
