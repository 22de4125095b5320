// numpy <-> aos::Image conversions (copy rules in bindings.h) and the bindings of image_io.h.
#include <cstring>
#include <filesystem>
#include <optional>

#include <pybind11/stl/filesystem.h>

#include "aos/image/image.h"
#include "aos/image/image_io.h"
#include "bindings.h"

namespace aos::python {
namespace {

using namespace pybind11::literals;

template <typename T>
Image CopyArray(const py::array& array, PixelType type, int border) {
  // Same dtype, made C-contiguous (a temporary copy only if it was not).
  auto contiguous = py::array_t<T, py::array::c_style>::ensure(array);
  if (!contiguous) throw py::error_already_set();
  const int height = static_cast<int>(contiguous.shape(0));
  const int width = static_cast<int>(contiguous.shape(1));
  const int channels = contiguous.ndim() == 3 ? static_cast<int>(contiguous.shape(2)) : 1;
  Image image(width, height, channels, type, border);
  image.CopyFrom(contiguous.data(), static_cast<ptrdiff_t>(width) * channels);
  return image;
}

}  // namespace

Image ImageFromArray(py::handle object, int border, const std::string& what) {
  py::array array = py::array::ensure(object);
  if (!array) {
    throw py::value_error(what + ": expected a numpy array (H, W) or (H, W, C), got " +
                          std::string(py::str(py::type::handle_of(object).attr("__name__"))));
  }
  const std::string dtype = py::str(array.dtype());
  if (array.ndim() != 2 && array.ndim() != 3) {
    throw py::value_error(what + ": expected an array of shape (H, W) or (H, W, C), got " +
                          std::to_string(array.ndim()) + " dimensions");
  }
  if (array.ndim() == 3 && (array.shape(2) < 1 || array.shape(2) > 4)) {
    throw py::value_error(what + ": expected 1 to 4 channels (last axis), got " +
                          std::to_string(array.shape(2)));
  }
  if (array.shape(0) < 1 || array.shape(1) < 1 || array.shape(0) > INT32_MAX / 4 ||
      array.shape(1) > INT32_MAX / 4) {
    throw py::value_error(what + ": image size " + std::to_string(array.shape(1)) + "x" +
                          std::to_string(array.shape(0)) + " is empty or too large");
  }
  if (py::isinstance<py::array_t<uint8_t>>(array)) return CopyArray<uint8_t>(array, PixelType::kU8, border);
  if (py::isinstance<py::array_t<uint16_t>>(array)) return CopyArray<uint16_t>(array, PixelType::kU16, border);
  if (py::isinstance<py::array_t<uint32_t>>(array)) return CopyArray<uint32_t>(array, PixelType::kU32, border);
  if (py::isinstance<py::array_t<float>>(array)) return CopyArray<float>(array, PixelType::kF32, border);
  if (py::isinstance<py::array_t<double>>(array)) {
    auto as_float = py::array_t<float, py::array::c_style | py::array::forcecast>::ensure(array);
    if (!as_float) throw py::error_already_set();
    return CopyArray<float>(as_float, PixelType::kF32, border);
  }
  throw py::value_error(what + ": unsupported dtype " + dtype +
                        " (expected uint8, uint16 or float32; float64 is converted to float32)");
}

bool ImagesEqual(const Image& a, const Image& b) {
  if (a.empty() || b.empty()) return a.empty() && b.empty();
  if (a.width() != b.width() || a.height() != b.height() || a.channels() != b.channels() ||
      a.type() != b.type()) {
    return false;
  }
  const size_t row_bytes =
      static_cast<size_t>(a.width()) * a.channels() * PixelTypeSize(a.type());
  for (int y = 0; y < a.height(); ++y) {
    if (std::memcmp(a.RawAt(0, y), b.RawAt(0, y), row_bytes) != 0) return false;
  }
  return true;
}

py::object ArrayFromImage(const Image& image) {
  if (image.empty()) return py::none();
  const auto value_size = static_cast<py::ssize_t>(PixelTypeSize(image.type()));
  const py::dtype dtype = py::dtype::from_args(py::str(PixelTypeName(image.type())));
  std::vector<py::ssize_t> shape{image.height(), image.width()};
  if (image.channels() > 1) shape.push_back(image.channels());

  if (image.border() != 0) {
    // Views keep a border for the sampler: hand out a plain copy, so the stored view (and its
    // replicated border) cannot be changed from Python.
    py::array array(dtype, shape);
    image.CopyTo(array.mutable_data(), static_cast<ptrdiff_t>(image.width()) * image.channels());
    return std::move(array);
  }
  // Share the storage: the capsule owns a copy of the Image, whose pixels are a shared_ptr.
  auto* owner = new Image(image);
  py::capsule base(owner, [](void* pointer) { delete static_cast<Image*>(pointer); });
  std::vector<py::ssize_t> strides{image.row_stride() * value_size, image.channels() * value_size};
  if (image.channels() > 1) strides.push_back(value_size);
  return py::array(dtype, shape, strides, owner->RawAt(0, 0), base);
}

void BindImage(py::module_& m) {
  m.def(
      "read_image",
      [](const std::filesystem::path& path) {
        Image image;
        {
          py::gil_scoped_release release;
          image = ReadImage(path.string(), /*border=*/0);
        }
        return ArrayFromImage(image);
      },
      "path"_a,
      "Reads an image file (PNG, TIFF, EXR, JPEG, ...). 8-bit and 16-bit files keep their type "
      "(uint8, uint16), everything else becomes float32. Returns (H, W) for one channel, else "
      "(H, W, C); the array owns the decoded pixels (no extra copy).");

  const WriteImageOptions defaults;
  m.def(
      "write_image",
      [](const std::filesystem::path& path, const py::handle& array, const std::string& sample_type,
         std::optional<double> range_min, std::optional<double> range_max, std::string description,
         const std::string& units, int png_compression_level) {
        WriteImageOptions options;
        options.png_compression_level = png_compression_level;
        options.sample_type = ParseSampleType(sample_type);
        options.units = ParsePixelTypeName(units, "units");
        if (range_min) options.range_min = *range_min;
        if (range_max) options.range_max = *range_max;
        options.description = std::move(description);
        const Image image = ImageFromArray(array, /*border=*/0, "write_image: " + path.string());
        py::gil_scoped_release release;
        WriteImage(path.string(), image, options);
      },
      "path"_a, "array"_a, "sample_type"_a = std::string(SampleTypeName(defaults.sample_type)),
      "range_min"_a = py::none(), "range_max"_a = py::none(),
      "description"_a = defaults.description,
      "units"_a = std::string(PixelTypeName(defaults.units)),
      "png_compression_level"_a = defaults.png_compression_level,
      "Writes an image (format from the extension). `array` (H, W) or (H, W, C) of dtype uint8, "
      "uint16, uint32 or float32 (float64 is converted to float32) is copied first. A float "
      "array's values are in the units of `units` ('uint8': 0..255, 'uint16': 0..65535, "
      "'float32': 0..1; aos renders keep their views' units); written to an integer format with "
      "sample_type 'auto' they take the depth of `units` (uint16 for 16-bit or float units) and "
      "[range_min, range_max] (default: the units' full range) maps to [0, max code]; the same "
      "rule as aos-render. sample_type: 'auto', 'uint8', 'uint16', 'uint32', 'float32'. "
      "png_compression_level: zlib level 0..9 of PNG files (1: fast). The file "
      "appears atomically; raises ValueError on failure.");
}

}  // namespace aos::python
