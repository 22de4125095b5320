#pragma once
// Shared pieces of the pybind11 module aos._core: the BindX entry points (one per binding file),
// glm <-> numpy conversions, numpy <-> aos::Image conversions, the Python progress sink and the
// kwargs protocol of the XxxOptions classes. Bindings adapt; they contain no algorithms.
//
// Copy rules for numpy (stated once here, repeated in the docstrings and in _core.pyi):
// - Vectors and matrices (glm types) are converted by value both ways: any array-like of the
//   right shape goes in (converted to float64), a new float64 array comes out. Mutating a returned
//   array does not change the object it came from.
// - Images going in (LightField.add_view, write_image) are always COPIED into aos::Image storage;
//   add_view adds the 1-pixel replicated border that views need. Accepted dtypes: uint8, uint16,
//   float32 (kept), float64 (converted to float32), and uint32 (write_image only; views reject
//   it). Any strides are accepted. Other dtypes raise ValueError naming the dtype.
// - Images coming out: 2-D (H, W) for one channel, (H, W, C) otherwise, dtype named by
//   PixelTypeName. Result images (border 0: read_image, IntegralResult.image/count) SHARE memory
//   with the C++ Image; the array keeps the pixel storage alive through a capsule. View images
//   (border 1) are returned as a COPY, so the stored view (and its border) cannot be changed.
#include <algorithm>
#include <atomic>
#include <chrono>
#include <cstdint>
#include <functional>
#include <mutex>
#include <optional>
#include <string>
#include <thread>
#include <type_traits>
#include <utility>
#include <vector>

#include <glm/glm.hpp>
#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>
#include <pybind11/stl.h>

#include "aos/geometry/lens.h"
#include "aos/geometry/pinhole.h"
#include "aos/geometry/rigid.h"
#include "aos/image/image.h"
#include "aos/lightfield/options_json.h"
#include "aos/render/focal_surface_json.h"
#include "aos/util/error.h"
#include "aos/util/option_fields.h"
#include "aos/util/progress.h"

namespace pybind11::detail {

#if PYBIND11_VERSION_MAJOR >= 3
#define AOS_NUMPY_IO_NAME(out) io_name("numpy.typing.ArrayLike", out)
#else
#define AOS_NUMPY_IO_NAME(out) const_name(out)
#endif

// glm::vec<N, double> <-> numpy float64 array of shape (N,). Accepts tuples, lists and arrays.
template <glm::length_t N>
struct type_caster<glm::vec<N, double, glm::defaultp>> {
  using Vec = glm::vec<N, double, glm::defaultp>;
  PYBIND11_TYPE_CASTER(Vec, AOS_NUMPY_IO_NAME("numpy.typing.NDArray[numpy.float64]"));

  bool load(handle src, bool /*convert*/) {
    if (!src || src.is_none() || PyUnicode_Check(src.ptr()) || PyBytes_Check(src.ptr())) {
      return false;
    }
    auto array = array_t<double, array::c_style | array::forcecast>::ensure(src);
    if (!array || array.ndim() != 1 || array.shape(0) != N) return false;
    for (glm::length_t i = 0; i < N; ++i) value[i] = array.at(i);
    return true;
  }

  static handle cast(const Vec& vec, return_value_policy /*policy*/, handle /*parent*/) {
    array_t<double> array(static_cast<ssize_t>(N));
    auto out = array.template mutable_unchecked<1>();
    for (glm::length_t i = 0; i < N; ++i) out(i) = vec[i];
    return array.release();
  }
};

// glm::dmat3 <-> numpy float64 array of shape (3, 3), row-major as written on paper
// (array[r, c] = m[c][r], GLM being column-major).
template <>
struct type_caster<glm::dmat3> {
  PYBIND11_TYPE_CASTER(glm::dmat3, AOS_NUMPY_IO_NAME("numpy.typing.NDArray[numpy.float64]"));

  bool load(handle src, bool /*convert*/) {
    if (!src || src.is_none() || PyUnicode_Check(src.ptr()) || PyBytes_Check(src.ptr())) {
      return false;
    }
    auto array = array_t<double, array::c_style | array::forcecast>::ensure(src);
    if (!array || array.ndim() != 2 || array.shape(0) != 3 || array.shape(1) != 3) return false;
    for (int r = 0; r < 3; ++r) {
      for (int c = 0; c < 3; ++c) value[c][r] = array.at(r, c);
    }
    return true;
  }

  static handle cast(const glm::dmat3& m, return_value_policy /*policy*/, handle /*parent*/) {
    array_t<double> array({3, 3});
    auto out = array.mutable_unchecked<2>();
    for (int r = 0; r < 3; ++r) {
      for (int c = 0; c < 3; ++c) out(r, c) = m[c][r];
    }
    return array.release();
  }
};

#undef AOS_NUMPY_IO_NAME

}  // namespace pybind11::detail

namespace aos::python {

namespace py = pybind11;

// A focal surface from what Python passes: a FocalSurface, a Mesh, a Heightfield, a Plane or a
// number (a horizontal plane); TypeError naming focal_surface otherwise. bind_render.cpp.
FocalSurface SurfaceFromPython(const py::object& value);

// Issues a DeprecationWarning with `message` (raises if warnings are errors). module.cpp.
void WarnDeprecated(const std::string& message);

void BindGeometry(py::module_& m);
void BindImage(py::module_& m);
void BindLightField(py::module_& m);
void BindRender(py::module_& m);
void BindSim(py::module_& m);
void BindMetrics(py::module_& m);
void BindCalib(py::module_& m);
void BindSfm(py::module_& m);
void BindDemo(py::module_& m);
void BindDetect(py::module_& m);
void BindPlan(py::module_& m);

// Python's `a == b` as a bool, numpy arrays compared whole (numpy.array_equal: same shape and
// values). Used by the __eq__ of options, cameras, poses and light fields.
bool ValuesEqual(const py::handle& a, const py::handle& b);

// `state` (what __getstate__ returned when pickling `class_name`) as a dict with exactly `keys`;
// raises ValueError naming a missing or unknown key (e.g. a pickle from another aos version).
py::dict StateDict(const py::handle& state, const std::string& class_name,
                   const std::vector<std::string>& keys);

// Exact equality of every field (bind_geometry.cpp); LensEqual includes the derived valid field.
bool RigidEqual(const Rigid3d& a, const Rigid3d& b);
bool PinholeEqual(const PinholeCamera& a, const PinholeCamera& b);
bool LensEqual(const LensCamera& a, const LensCamera& b);

// Whether two images have the same size, channels, pixel type and pixels (borders ignored).
bool ImagesEqual(const Image& a, const Image& b);

// Copies a numpy array (or anything numpy.asarray accepts) of dtype uint8, uint16, uint32,
// float32 or float64 (-> float32) and shape (H, W) or (H, W, C), C in 1..4, into a new Image with
// `border` replicated border pixels. Throws ValueError "<what>: ..." naming the dtype or shape.
Image ImageFromArray(py::handle object, int border, const std::string& what);

// The pixels of `image` as a numpy array: shared (no copy, the array owns a reference to the
// storage) when the image has no border, copied otherwise. None for an empty image.
py::object ArrayFromImage(const Image& image);

// A ProgressSink forwarding to an optional Python callable progress(stage, done, total).
//
// Start/Advance/Cancelled may run on any thread while the GIL is released. Only the thread that
// created the sink (the Python caller, which is also OpenMP's master thread) ever touches Python:
// at most every kReportInterval (plus at the start of a stage and once when done == total) it
// takes the GIL, runs PyErr_CheckSignals() (so Ctrl-C works) and then the callback. A Python
// error from either is stored and makes Cancelled() return true; the binding re-raises it with
// RethrowIfFailed() once the C++ call has returned or thrown.
class PythonProgress final : public ProgressSink {
 public:
  static constexpr std::chrono::milliseconds kReportInterval{100};

  // Call with the GIL held. `callback` may be None (signals are still checked).
  explicit PythonProgress(py::object callback);
  ~PythonProgress() override;

  void Start(const std::string& stage, int64_t total) override;
  void Advance(int64_t units) override;
  bool Cancelled() override;

  // Call with the GIL held, after the work returned: reports done == total if the last stage
  // finished without that report (its last units were done on a worker thread).
  void Finish();
  // Call with the GIL held: raises the stored Python error, if any.
  void RethrowIfFailed();

 private:
  // Owner thread only. `force` skips the time throttle.
  void Report(bool force);

  py::object callback_;
  const std::thread::id owner_;
  std::mutex stage_mutex_;
  std::string stage_;
  std::atomic<int64_t> total_{0};
  std::atomic<int64_t> done_{0};
  std::atomic<bool> failed_{false};
  // Owner thread only.
  std::chrono::steady_clock::time_point last_report_{};
  bool final_reported_ = false;
  std::optional<py::error_already_set> error_;
};

// Runs `compute(ProgressSink*)` with the GIL released and a PythonProgress wired to `callback`.
// Re-raises a Python error raised by the callback (or by a signal handler) in preference to the
// aos::Cancelled or other error it caused. Call with the GIL held.
template <typename Compute>
auto RunWithProgress(const py::object& callback, Compute&& compute) {
  PythonProgress sink(callback);
  std::optional<decltype(compute(static_cast<ProgressSink*>(nullptr)))> result;
  try {
    py::gil_scoped_release release;
    result.emplace(compute(static_cast<ProgressSink*>(&sink)));
  } catch (...) {
    // The GIL is already back here: `release` was destroyed while unwinding.
    sink.RethrowIfFailed();
    throw;
  }
  sink.RethrowIfFailed();
  sink.Finish();
  return std::move(*result);
}

// The Python annotation of a bound C++ type, as the stubs write it: read ("float", "list[int]",
// "Plane | None") or `given` (what the setter takes: "Sequence[int]", "Plane | float",
// "MergeMethod | Literal['sobel', ...]").
template <typename T>
std::string PythonTypeName(bool given = false) {
  if constexpr (std::is_same_v<T, bool>) {
    return "bool";
  } else if constexpr (std::is_integral_v<T>) {
    return "int";
  } else if constexpr (std::is_floating_point_v<T>) {
    return "float";
  } else if constexpr (std::is_same_v<T, std::string>) {
    return "str";
  } else if constexpr (options_json::IsVector<T>::value || options_json::IsArray<T>::value) {
    return (given ? "Sequence[" : "list[") + PythonTypeName<typename T::value_type>(given) + "]";
  } else if constexpr (std::is_same_v<T, Plane>) {
    return given ? "Plane | float" : "Plane";
  } else if constexpr (options_json::IsOptional<T>::value) {
    return PythonTypeName<typename T::value_type>(given) + " | None";
  } else if constexpr (std::is_same_v<T, FocalSurface>) {
    return given ? "FocalSurface | Mesh | Heightfield | Plane | float" : "FocalSurface";
  } else {
    const py::detail::type_info* info = py::detail::get_type_info(typeid(T));
    if (info == nullptr) throw std::logic_error("PythonTypeName: an unbound type");
    const std::string name = py::str(py::handle(reinterpret_cast<PyObject*>(info->type)).attr("__name__"));
    if constexpr (std::is_enum_v<T>) {
      if (given) {
        std::string names;
        for (const auto& entry : EnumNames<T>::kValues) {
          names += (names.empty() ? "'" : ", '") + std::string(entry.second) + "'";
        }
        return name + " | Literal[" + names + "]";
      }
    }
    return name;
  }
}

// A value of the bound enum E from Python: an E, or the name of one of its values. Raises
// ValueError naming `field` and the choices for an unknown name (TypeError for other types).
template <typename E>
E EnumFromPython(const py::object& value, const std::string& field) {
  if (py::isinstance<py::str>(value)) {
    try {
      return EnumFromName<E>(value.cast<std::string>(), field);
    } catch (const std::invalid_argument& error) {
      throw py::value_error(error.what());
    }
  }
  try {
    return value.cast<E>();
  } catch (const py::cast_error&) {
    throw py::type_error(field + ": expected " + PythonTypeName<E>() +
                         " or the name of one of its values, got " +
                         py::str(py::type::of(value).attr("__name__")).cast<std::string>());
  }
}

// Binds enum E with the names of EnumNames<E> (util/option_fields.h).
template <typename E>
py::enum_<E> BindEnum(py::module_& m, const char* name, const char* doc) {
  py::enum_<E> bound(m, name, doc);
  for (const auto& [value, value_name] : EnumNames<E>::kValues) bound.value(value_name, value);
  return bound;
}

// One row of a field table as Python sees it (the class attribute `_field_table`): a dict of
// name, type, given, unit, range, help and flag (tools/options.py, the viewer's command line).
template <class Spec>
py::dict FieldRow(const Spec& spec) {
  using T = typename Spec::Type;
  py::dict row;
  row["name"] = spec.name;
  row["type"] = PythonTypeName<T>(false);
  row["given"] = PythonTypeName<T>(true);
  if (std::is_same_v<T, std::string> && spec.range.choices != nullptr) {
    std::string literal;  // Literal['scan', 'grid']: type checkers catch a misspelt choice
    for (const std::string& choice : spec.range.Choices()) {
      literal += (literal.empty() ? "Literal['" : ", '") + choice + "'";
    }
    literal += "]";
    row["type"] = literal;
    row["given"] = literal;
  }
  row["unit"] = spec.unit;
  row["range"] = spec.range.IsAny() ? std::string() : spec.range.Text();
  row["help"] = spec.help;
  row["flag"] = FlagOfField(spec.name, spec.flag);  // aos-render's (cpp/exe/cli.h)
  return row;
}

// Every row of `Options`' table (FieldRow), in order.
template <class Options>
py::tuple FieldTable() {
  py::list table;
  Options::Fields([&table](const auto& spec) { table.append(FieldRow(spec)); });
  return py::tuple(table);
}

// Binds an XxxOptions struct as a Python class whose read/write properties are exactly the
// struct's fields (defaults therefore come from C++), with
//   __init__(**kwargs)  (unknown names raise TypeError), _fields (names in declaration order),
//   __repr__ listing the fields, __eq__ comparing them, __copy__ and __deepcopy__ (C++ copies),
//   and pickling (the state is a dict of the fields, nested options pickled the same way).
//
// `Bases`: the Options block the struct derives from (ApertureOptions, render/aperture.h), bound
// before it: Python then has the same class hierarchy, and the stub types the block's fields
// once, on the base (tools/options.py).
template <typename Options, typename... Bases>
class OptionsClass {
 public:
  OptionsClass(py::module_& m, const char* name, const char* doc) : class_(m, name, doc) {}

  // An enum field also takes its value's name ("robust" for MergeMethod.robust), in the
  // keyword constructor and on assignment; an unknown name raises ValueError with the choices.
  template <typename T>
  OptionsClass& Field(const char* name, T Options::*member, const char* doc) {
    if constexpr (std::is_enum_v<T>) {
      const std::string field = name;
      class_.def_property(
          name, [member](const Options& options) { return options.*member; },
          [member, field](Options& options, const py::object& value) {
            options.*member = EnumFromPython<T>(value, field);
          },
          doc);
    } else {
      class_.def_readwrite(name, member, doc);
    }
    fields_.emplace_back(name);
    return *this;
  }

  // Binds every field of the struct's table (util/option_fields.h), in its order, with the
  // table's help as docstring, and records the table as the class attribute `_field_table`
  // (a tuple of dicts: name, type, given, unit, range, help, flag) that tools/options.py reads.
  // Also adds to_json() and from_json(text) (lightfield/options_json.h).
  OptionsClass& Table() {
    static_assert(kHasFieldTable<Options>, "Table() needs a field table");
    py::list table;
    Options::Fields([this, &table](const auto& spec) {
      using T = typename std::decay_t<decltype(spec)>::Type;
      T Options::*member = spec.member;  // a field of a base block (aperture.h) too
      const std::string field = spec.name;
      if constexpr (std::is_same_v<T, FocalSurface>) {
        Property(
            spec.name, [member](const Options& o) { return o.*member; },
            [member](Options& o, const py::object& value) { o.*member = SurfaceFromPython(value); },
            spec.help);
      } else if constexpr (options_json::IsOptional<T>::value) {
        Property(
            spec.name,
            [member](const Options& o) -> py::object {
              if (!(o.*member)) return py::none();
              return py::cast(*(o.*member));
            },
            [member](Options& o, const py::object& value) {
              if (value.is_none()) {
                (o.*member).reset();
              } else {
                o.*member = value.cast<typename T::value_type>();
              }
            },
            spec.help);
      } else {
        Field(spec.name, member, spec.help);
      }
      table.append(FieldRow(spec));
    });
    class_.attr("_field_table") = py::tuple(table);
    const std::string class_name = py::str(class_.attr("__name__"));
    class_.def(
        "to_json",
        [](const Options& options) { return OptionsToJson(options).dump(); },
        "The options as one JSON object (a focal surface as its plane or its file; infinities as "
        "\"inf\"), what from_json reads.");
    class_.def_static(
        "from_json",
        [class_name](const std::string& text) {
          nlohmann::json json;
          try {
            json = nlohmann::json::parse(text);
          } catch (const nlohmann::json::exception& error) {
            throw py::value_error(class_name + " JSON: not JSON (" + error.what() + ")");
          }
          return OptionsFromJson<Options>(json, JsonPath(class_name + " JSON"));
        },
        py::arg("text"),
        "Default options with the JSON object's members read in (unknown keys and bad values "
        "raise ValueError naming the key).");
    return *this;
  }

  // A deprecated spelling `name` of the field `replacement`, kept for one release: reading or
  // setting it (also as a constructor keyword) warns with DeprecationWarning naming the
  // replacement; `read` converts the replacement's value to the old form (None: as it is);
  // a value set is passed to the replacement's setter as it is. Not in _fields, repr, ==, pickle
  // or JSON.
  OptionsClass& Deprecated(const char* name, const char* replacement,
                           std::function<py::object(const py::object&)> read = nullptr) {
    const std::string old_name = name, new_name = replacement;
    const std::string class_name = py::str(class_.attr("__name__"));
    const std::string message = class_name + "." + old_name + " is deprecated; use " + new_name;
    class_.def_property(
        name,
        [new_name, message, read](const py::object& self) {
          WarnDeprecated(message);
          py::object value = self.attr(new_name.c_str());
          return read ? read(value) : value;
        },
        [new_name, message](const py::object& self, const py::object& value) {
          WarnDeprecated(message);
          py::setattr(self, new_name.c_str(), value);
        },
        ("Deprecated: use " + new_name + ".").c_str());
    deprecated_.emplace_back(old_name, new_name);
    return *this;
  }

  // Adds the protocol methods; call after the last Field().
  py::class_<Options, Bases...>& Finish() {
    const std::vector<std::string> fields = fields_;
    std::vector<std::string> accepted = fields_;
    for (const auto& spelling : deprecated_) accepted.push_back(spelling.first);
    const std::string class_name = py::str(class_.attr("__name__"));
    const auto spellings = deprecated_;
    class_.def(py::init([fields, accepted, spellings, class_name](const py::kwargs& kwargs) {
                 py::object options = py::cast(Options{});
                 for (const auto& [old_name, new_name] : spellings) {
                   if (kwargs.contains(old_name) && kwargs.contains(new_name)) {
                     throw py::type_error(class_name + "(): give " + new_name + " or " +
                                          old_name + " (its deprecated spelling), not both");
                   }
                 }
                 for (const auto& item : kwargs) {
                   const std::string key = py::str(item.first);
                   if (std::find(accepted.begin(), accepted.end(), key) == accepted.end()) {
                     throw py::type_error(class_name + "() got an unexpected keyword argument '" +
                                          key + "' (options: " + Join(fields) + ")");
                   }
                   py::setattr(options, item.first, item.second);
                 }
                 return options.cast<Options>();
               }),
               "Default options, with any field given by name overriding its default.");
    py::tuple names(fields.size());
    for (size_t i = 0; i < fields.size(); ++i) names[i] = py::str(fields[i]);
    class_.attr("_fields") = names;
    py::dict deprecated;  // old spelling -> field (aos._Router renames keywords through it)
    for (const auto& [old_name, new_name] : deprecated_) deprecated[py::str(old_name)] = new_name;
    class_.attr("_deprecated") = deprecated;
    class_.def("__repr__", [fields, class_name](const py::object& self) {
      std::string text = class_name + "(";
      for (size_t i = 0; i < fields.size(); ++i) {
        if (i > 0) text += ", ";
        text += fields[i] + "=" + std::string(py::repr(self.attr(fields[i].c_str())));
      }
      return text + ")";
    });
    class_.def(
        "__eq__",
        [fields](const py::object& self, const py::object& other) -> py::object {
          if (!py::type::handle_of(other).is(py::type::handle_of(self))) {  // the same class, not a base
            return py::reinterpret_borrow<py::object>(Py_NotImplemented);
          }
          for (const std::string& field : fields) {
            if (!ValuesEqual(self.attr(field.c_str()), other.attr(field.c_str()))) {
              return py::bool_(false);
            }
          }
          return py::bool_(true);
        },
        py::arg("other"), "Whether every field is equal.");
    class_.def("__copy__", [](const Options& self) { return Options(self); });
    class_.def("__deepcopy__", [](const Options& self, const py::dict&) { return Options(self); },
               py::arg("memo"));
    class_.def(py::pickle(
        [fields](const py::object& self) {
          py::dict state;
          for (const std::string& field : fields) state[py::str(field)] = self.attr(field.c_str());
          return state;
        },
        [fields, class_name](const py::object& state) {
          const py::dict values = StateDict(state, class_name, fields);
          py::object options = py::cast(Options{});
          for (const std::string& field : fields) {
            py::setattr(options, field.c_str(), values[py::str(field)]);
          }
          return options.cast<Options>();
        }));
    return class_;
  }

  // A field bound through a getter and a setter (a value needing conversion, e.g. a shared
  // pointer), recorded like Field for the protocol methods.
  template <class Getter, class Setter>
  OptionsClass& Property(const char* name, Getter getter, Setter setter, const char* doc) {
    class_.def_property(name, getter, setter, doc);
    fields_.emplace_back(name);
    return *this;
  }

  py::class_<Options, Bases...>& cls() { return class_; }

 private:
  static std::string Join(const std::vector<std::string>& names) {
    std::string text;
    for (const std::string& name : names) text += (text.empty() ? "" : ", ") + name;
    return text;
  }

  py::class_<Options, Bases...> class_;
  std::vector<std::string> fields_;
  std::vector<std::pair<std::string, std::string>> deprecated_;  // old spelling, field
};

}  // namespace aos::python
