#pragma once
// The JSON form of any Options struct with a field table (util/option_fields.h): one object, a
// member per field, named as the field, in table order. Written by OptionsToJson, read back by
// OptionsFromJson through the strict codec of json_codec.h (one error style: "<where>: /path:
// reason", unknown keys refused, missing keys keep the struct's default). What the CLI hands to
// Python (`view`, `map --workers`) and what Python's XxxOptions.to_json()/from_json() use.
//
// Values: bool; whole numbers; numbers, with infinities written as the strings "inf"/"-inf"
// (JSON has none; NaN is refused both ways); strings; enums by name (EnumNames); lists and
// fixed-size arrays of these; a Plane {"point", "normal"} and a pose {"rotation",
// "translation"} as json_codec.h writes them; an optional value as null or the value; a nested
// Options struct as its own object. Other types are written and read by a specialisation of
// JsonForm<T> (a FocalSurface: render/focal_surface_json.h, which a caller that writes options
// holding one includes; without it the code does not compile).
//
// Internal header: it includes nlohmann/json (through json_codec.h).
#include <array>
#include <cmath>
#include <cstdint>
#include <limits>
#include <memory>
#include <optional>
#include <string>
#include <type_traits>
#include <vector>

#include "aos/lightfield/json_codec.h"
#include "aos/util/option_fields.h"

namespace aos {
// The JSON form of a field type the codec does not know (specialise: static
// nlohmann::ordered_json ToJson(const T&) and static T FromJson(const nlohmann::json&,
// const JsonPath&)).
template <class T>
struct JsonForm;

namespace options_json {

template <class T>
struct IsVector : std::false_type {};
template <class T>
struct IsVector<std::vector<T>> : std::true_type {};
template <class T>
struct IsArray : std::false_type {};
template <class T, size_t N>
struct IsArray<std::array<T, N>> : std::true_type {};
template <class T>
struct IsOptional : std::false_type {};
template <class T>
struct IsOptional<std::optional<T>> : std::true_type {};

template <class T>
nlohmann::ordered_json ValueToJson(const T& value);
template <class T>
T ValueFromJson(const nlohmann::json& json, const JsonPath& at);

}  // namespace options_json

template <class Options>
nlohmann::ordered_json OptionsToJson(const Options& options) {
  nlohmann::ordered_json object = nlohmann::ordered_json::object();
  Options::Fields([&](const auto& field) {
    try {
      object[field.name] = options_json::ValueToJson(options.*(field.member));
    } catch (const std::invalid_argument& error) {
      ThrowInvalid(std::string(field.name) + ": " + error.what());
    }
  });
  return object;
}

// Reads the members of `json` into `options`: fields not given keep their value (a nested
// Options struct given is read whole, its members not given taking their defaults).
template <class Options>
void OptionsFromJson(const nlohmann::json& json, const JsonPath& at, Options* options) {
  if (!json.is_object()) at.Fail("expected an object, got " + DescribeJson(json));
  std::string known;
  Options::Fields([&](const auto& field) {
    known += (known.empty() ? "" : ", ") + std::string(field.name);
  });
  for (const auto& item : json.items()) {
    bool found = false;
    Options::Fields([&](const auto& field) {
      if (item.key() != field.name) return;
      found = true;
      using T = typename std::decay_t<decltype(field)>::Type;
      options->*(field.member) = options_json::ValueFromJson<T>(item.value(), at / item.key());
    });
    if (!found) (at / item.key()).Fail("unknown key (known: " + known + ")");
  }
}

// Default options with `json`'s members read in.
template <class Options>
Options OptionsFromJson(const nlohmann::json& json, const JsonPath& at) {
  Options options;
  OptionsFromJson(json, at, &options);
  return options;
}

namespace options_json {

template <class T>
nlohmann::ordered_json ValueToJson(const T& value) {
  if constexpr (std::is_same_v<T, bool> || std::is_integral_v<T> ||
                std::is_same_v<T, std::string>) {
    return value;
  } else if constexpr (std::is_floating_point_v<T>) {
    if (std::isinf(value)) return value > 0 ? "inf" : "-inf";
    if (std::isnan(value)) ThrowInvalid("a NaN option value has no JSON form");
    return static_cast<double>(value);
  } else if constexpr (std::is_enum_v<T>) {
    return EnumName(value);
  } else if constexpr (IsVector<T>::value || IsArray<T>::value) {
    nlohmann::ordered_json array = nlohmann::ordered_json::array();
    for (const auto& element : value) array.push_back(ValueToJson(element));
    return array;
  } else if constexpr (IsOptional<T>::value) {
    return value ? ValueToJson(*value) : nlohmann::ordered_json(nullptr);
  } else if constexpr (std::is_same_v<T, Plane>) {
    return PlaneToJson(value);
  } else if constexpr (std::is_same_v<T, Rigid3d>) {
    return PoseToJson(value);
  } else if constexpr (kHasFieldTable<T>) {
    return OptionsToJson(value);
  } else {
    return JsonForm<T>::ToJson(value);
  }
}

template <class T>
T ValueFromJson(const nlohmann::json& json, const JsonPath& at) {
  if constexpr (std::is_same_v<T, bool>) {
    if (!json.is_boolean()) at.Fail("expected true or false, got " + DescribeJson(json));
    return json.get<bool>();
  } else if constexpr (std::is_integral_v<T>) {
    // Exact for every whole number of T (int64 included: read as an integer, not a double).
    if (json.is_number_float()) {  // 5.0: whole numbers written as floats are taken
      const double number = json.get<double>();
      const double lowest = static_cast<double>(std::numeric_limits<T>::min());
      const double beyond = static_cast<double>(std::numeric_limits<T>::max()) + 1.0;
      if (number == std::floor(number) && number >= lowest && number < beyond) {
        return static_cast<T>(number);
      }
    }
    if (!json.is_number_integer()) {
      at.Fail("expected a whole number, got " + DescribeJson(json));
    }
    if (json.is_number_unsigned()) {
      const uint64_t value = json.get<uint64_t>();
      if (value > static_cast<uint64_t>(std::numeric_limits<T>::max())) {
        at.Fail("expected a whole number in " + std::to_string(std::numeric_limits<T>::min()) +
                ".." + std::to_string(std::numeric_limits<T>::max()) + ", got " +
                DescribeJson(json));
      }
      return static_cast<T>(value);
    }
    const int64_t value = json.get<int64_t>();
    if (value < static_cast<int64_t>(std::numeric_limits<T>::min()) ||
        (value > 0 && static_cast<uint64_t>(value) >
                          static_cast<uint64_t>(std::numeric_limits<T>::max()))) {
      at.Fail("expected a whole number in " + std::to_string(std::numeric_limits<T>::min()) +
              ".." + std::to_string(std::numeric_limits<T>::max()) + ", got " +
              DescribeJson(json));
    }
    return static_cast<T>(value);
  } else if constexpr (std::is_floating_point_v<T>) {
    if (json.is_string()) {
      const std::string text = json.get<std::string>();
      if (text == "inf" || text == "infinity") return std::numeric_limits<T>::infinity();
      if (text == "-inf" || text == "-infinity") return -std::numeric_limits<T>::infinity();
      at.Fail("expected a number, \"inf\" or \"-inf\", got " + DescribeJson(json));
    }
    return static_cast<T>(ReadJsonNumber(json, at));
  } else if constexpr (std::is_same_v<T, std::string>) {
    if (!json.is_string()) at.Fail("expected a string, got " + DescribeJson(json));
    return json.get<std::string>();
  } else if constexpr (std::is_enum_v<T>) {
    if (!json.is_string()) {
      at.Fail("expected one of " + EnumChoices<T>() + ", got " + DescribeJson(json));
    }
    const std::string name = json.get<std::string>();
    for (const auto& [value, candidate] : EnumNames<T>::kValues) {
      if (name == candidate) return value;
    }
    at.Fail("unknown value '" + name + "' (one of " + EnumChoices<T>() + ")");
  } else if constexpr (IsVector<T>::value) {
    if (!json.is_array()) at.Fail("expected a list, got " + DescribeJson(json));
    T values;
    values.reserve(json.size());
    for (size_t i = 0; i < json.size(); ++i) {
      values.push_back(ValueFromJson<typename T::value_type>(json[i], at / i));
    }
    return values;
  } else if constexpr (IsArray<T>::value) {
    T values{};
    if (!json.is_array() || json.size() != values.size()) {
      at.Fail("expected a list of " + std::to_string(values.size()) + ", got " +
              DescribeJson(json));
    }
    for (size_t i = 0; i < values.size(); ++i) {
      values[i] = ValueFromJson<typename T::value_type>(json[i], at / i);
    }
    return values;
  } else if constexpr (IsOptional<T>::value) {
    if (json.is_null()) return T{};
    return T{ValueFromJson<typename T::value_type>(json, at)};
  } else if constexpr (std::is_same_v<T, Plane>) {
    return ReadPlaneJson(json, at);
  } else if constexpr (std::is_same_v<T, Rigid3d>) {
    return ReadPoseJson(json, at);
  } else if constexpr (kHasFieldTable<T>) {
    return OptionsFromJson<T>(json, at);
  } else {
    return JsonForm<T>::FromJson(json, at);
  }
}

}  // namespace options_json
}  // namespace aos
