#include "aos/sim/scene.h"

#include <algorithm>
#include <filesystem>
#include <limits>
#include <set>
#include <sstream>

#include <nlohmann/json.hpp>

#include "aos/image/image_io.h"
#include "aos/lightfield/json_codec.h"
#include "aos/util/error.h"
#include "aos/util/file_util.h"
#include "aos/util/json_file.h"

namespace fs = std::filesystem;

namespace aos {
namespace {

using nlohmann::json;
using ojson = nlohmann::ordered_json;

std::string Join(const std::string& path, const std::string& key) {
  return path.empty() ? key : path + "." + key;
}

// The JSON pointer of a key path written with dots and brackets ("ground.texture.colors[1]" ->
// "/ground/texture/colors/1"; "" -> the document). Text after a space is a note kept as it is
// ("sampling (view 3)" -> "/sampling (view 3)"). Paths are built in the readable form and turned
// into pointers where an error is raised, so that every error has the codec's form
// (lightfield/json_codec.h): "<file>: /a/b/0: <reason>".
std::string PointerOf(const std::string& path) {
  if (path.empty()) return "";
  const size_t space = path.find(' ');
  const std::string keys = path.substr(0, space);
  std::string pointer = "/";
  for (char c : keys) {
    if (c == '.' || c == '[') {
      pointer += '/';
    } else if (c != ']') {
      pointer += c;
    }
  }
  return space == std::string::npos ? pointer : pointer + path.substr(space);
}

// One JSON object being read: every key must be read (or it is unknown, an error), every value
// must have the expected type, read by the codec's readers (json_codec.h). Errors read
// "<source>: <JSON pointer>: <reason>".
class Reader {
 public:
  Reader(const json& object, std::string path, const std::string& source)
      : object_(object), path_(std::move(path)), source_(source) {
    if (!object_.is_object()) Fail(path_, "expected an object, got " + DescribeJson(object_));
  }

  [[noreturn]] void Fail(const std::string& path, const std::string& reason) const {
    At(path).Fail(reason);
  }
  JsonPath At(const std::string& path) const { return JsonPath(source_, PointerOf(path)); }

  bool Has(const std::string& key) {
    allowed_.insert(key);
    return object_.contains(key);
  }

  const json& Get(const std::string& key) {
    allowed_.insert(key);
    return object_.at(key);
  }

  double Number(const std::string& key, double fallback) {
    if (!Has(key)) return fallback;
    return NumberOf(Get(key), Join(path_, key));
  }

  int Int(const std::string& key, int fallback) {
    if (!Has(key)) return fallback;
    return IntOf(Get(key), Join(path_, key));
  }

  bool Bool(const std::string& key, bool fallback) {
    if (!Has(key)) return fallback;
    const json& value = Get(key);
    if (!value.is_boolean()) Fail(Join(path_, key), "expected true or false, got " + DescribeJson(value));
    return value.get<bool>();
  }

  std::string String(const std::string& key, const std::string& fallback) {
    if (!Has(key)) return fallback;
    const json& value = Get(key);
    if (!value.is_string()) Fail(Join(path_, key), "expected a string, got " + DescribeJson(value));
    return value.get<std::string>();
  }

  template <size_t N>
  std::array<double, N> Numbers(const std::string& key, const std::array<double, N>& fallback) {
    if (!Has(key)) return fallback;
    return NumbersOf<N>(Get(key), Join(path_, key));
  }

  // A colour: one number (grey) or [r, g, b].
  Rgb Color(const std::string& key, const Rgb& fallback) {
    if (!Has(key)) return fallback;
    return ColorOf(Get(key), Join(path_, key));
  }

  Reader Child(const std::string& key) { return Reader(Get(key), Join(path_, key), source_); }

  const json& Array(const std::string& key) {
    const json& value = Get(key);
    if (!value.is_array()) Fail(Join(path_, key), "expected a list, got " + DescribeJson(value));
    return value;
  }

  const std::string& path() const { return path_; }
  const std::string& source() const { return source_; }

  // Every key must have been asked for.
  void Finish() const {
    for (auto it = object_.begin(); it != object_.end(); ++it) {
      if (allowed_.count(it.key()) == 0) {
        std::string known;
        for (const std::string& key : allowed_) known += (known.empty() ? "" : ", ") + key;
        (At(path_) / it.key()).Fail("unknown key (known: " + known + ")");  // escaped (RFC 6901)
      }
    }
  }

  double NumberOf(const json& value, const std::string& path) const {
    return ReadJsonNumber(value, At(path));
  }

  int IntOf(const json& value, const std::string& path) const {
    return ReadJsonInt(value, At(path), std::numeric_limits<int>::min(),
                       std::numeric_limits<int>::max());
  }

  template <size_t N>
  std::array<double, N> NumbersOf(const json& value, const std::string& path) const {
    if (!value.is_array() || value.size() != N) {
      Fail(path, "expected a list of " + std::to_string(N) + " numbers, got " + DescribeJson(value));
    }
    std::array<double, N> numbers{};
    for (size_t i = 0; i < N; ++i) {
      numbers[i] = NumberOf(value[i], path + "[" + std::to_string(i) + "]");
    }
    return numbers;
  }

  Rgb ColorOf(const json& value, const std::string& path) const {
    if (value.is_number()) {
      const double grey = NumberOf(value, path);
      return Rgb{grey, grey, grey};
    }
    if (!value.is_array() || value.size() != 3) {
      Fail(path, "expected a number (grey) or a list [r, g, b], got " + DescribeJson(value));
    }
    return NumbersOf<3>(value, path);
  }

 private:
  const json& object_;
  std::string path_;
  const std::string& source_;
  std::set<std::string> allowed_;
};

const char* TextureKindName(TextureSpec::Kind kind) {
  switch (kind) {
    case TextureSpec::Kind::kConstant: return "constant";
    case TextureSpec::Kind::kChecker: return "checker";
    case TextureSpec::Kind::kChart: return "chart";
    case TextureSpec::Kind::kNoise: return "noise";
    case TextureSpec::Kind::kImage: return "image";
  }
  return "?";
}

TextureSpec ReadTexture(Reader r, const TextureSpec& fallback, const std::string& base_dir) {
  TextureSpec t = fallback;
  const std::string type = r.String("type", TextureKindName(fallback.kind));
  using Kind = TextureSpec::Kind;
  if (type == "constant") {
    t.kind = Kind::kConstant;
    t.color_a = r.Color("color", t.color_a);
  } else if (type == "checker" || type == "noise") {
    t.kind = type == "checker" ? Kind::kChecker : Kind::kNoise;
    t.square = r.Number("square", t.square);
    if (type == "noise") {
      const int seed = r.Int("seed", static_cast<int>(t.seed));
      if (seed < 0) r.Fail(Join(r.path(), "seed"), "must be >= 0");
      t.seed = static_cast<uint32_t>(seed);
    }
  } else if (type == "chart") {
    t.kind = Kind::kChart;
    t.patch = r.Number("patch", t.patch);
    if (r.Has("squares")) {
      const json& squares = r.Array("squares");
      t.squares.clear();
      for (size_t i = 0; i < squares.size(); ++i) {
        t.squares.push_back(
            r.NumberOf(squares[i], Join(r.path(), "squares") + "[" + std::to_string(i) + "]"));
      }
    }
  } else if (type == "image") {
    t.kind = Kind::kImage;
    const std::string path = r.String("path", "");
    if (path.empty()) r.Fail(Join(r.path(), "path"), "is required for an image texture");
    t.image_path = fs::absolute(fs::path(base_dir) / path).lexically_normal().string();
    if (fs::path(path).is_absolute()) t.image_path = path;
    t.size = r.Numbers<2>("size", t.size);
    try {
      t.image = std::make_shared<const Image>(ReadImage(t.image_path));
    } catch (const std::invalid_argument& error) {
      r.Fail(Join(r.path(), "path"), error.what());
    }
  } else {
    r.Fail(Join(r.path(), "type"),
           "\"" + type + "\" is not one of constant, checker, chart, noise, image");
  }
  if (t.kind == Kind::kChecker || t.kind == Kind::kChart || t.kind == Kind::kNoise) {
    if (r.Has("colors")) {
      const json& colors = r.Array("colors");
      if (colors.size() != 2) r.Fail(Join(r.path(), "colors"), "must hold two colours");
      t.color_a = r.ColorOf(colors[0], Join(r.path(), "colors") + "[0]");
      t.color_b = r.ColorOf(colors[1], Join(r.path(), "colors") + "[1]");
    }
  }
  r.Finish();
  return t;
}

std::array<double, 2> Numbers2(Reader& r, const std::string& key, std::array<double, 2> fallback) {
  return r.Numbers<2>(key, fallback);
}

TextureSpec DefaultTargetTexture() {
  TextureSpec t;
  t.kind = TextureSpec::Kind::kChecker;
  t.square = 0.2;
  t.color_a = Rgb{0.95, 0.25, 0.1};
  t.color_b = Rgb{0.95, 0.95, 0.9};
  return t;
}

// ---- Check() helpers: "<source>: <JSON pointer>: <reason>", as the reader's ----

struct Checker {
  const std::string& source;
  [[noreturn]] void Fail(const std::string& path, const std::string& reason) const {
    JsonPath(source, PointerOf(path)).Fail(reason);
  }
  void Positive(double value, const std::string& path) const {
    if (!(value > 0.0) || !std::isfinite(value)) Fail(path, FormatNumber(value) + " must be > 0");
  }
  void InRange(double value, double lo, double hi, const std::string& path,
               bool hi_open = false) const {
    const bool ok = std::isfinite(value) && value >= lo && (hi_open ? value < hi : value <= hi);
    if (!ok) {
      Fail(path, FormatNumber(value) + " is outside [" + FormatNumber(lo) + ", " +
                     FormatNumber(hi) + (hi_open ? ")" : "]"));
    }
  }
  void IntRange(int value, int lo, int hi, const std::string& path) const {
    if (value < lo || value > hi) {
      Fail(path, std::to_string(value) + " is outside " + std::to_string(lo) + ".." +
                     std::to_string(hi));
    }
  }
  void Color(const Rgb& c, const std::string& path) const {
    for (double v : c) InRange(v, 0.0, 1.0, path);
  }
  void Range(const std::array<double, 2>& r, const std::string& path) const {
    Positive(r[0], path + "[0]");
    if (r[1] < r[0]) Fail(path, "the upper end is below the lower end");
  }
  void Area(const std::array<double, 4>& a, const std::string& path) const {
    if (a == std::array<double, 4>{0, 0, 0, 0}) return;
    if (!(a[2] > a[0]) || !(a[3] > a[1])) Fail(path, "must be [xmin, ymin, xmax, ymax] with max > min");
  }
  void Texture(const TextureSpec& t, const std::string& path) const {
    const bool constant = t.kind == TextureSpec::Kind::kConstant;
    Color(t.color_a, path + (constant ? ".color" : ".colors[0]"));
    Color(t.color_b, path + ".colors[1]");
    Positive(t.square, path + ".square");
    Positive(t.patch, path + ".patch");
    if (t.kind == TextureSpec::Kind::kChart && t.squares.empty()) Fail(path + ".squares", "is empty");
    for (double s : t.squares) Positive(s, path + ".squares");
    if (t.kind == TextureSpec::Kind::kImage) {
      Positive(t.size[0], path + ".size[0]");
      Positive(t.size[1], path + ".size[1]");
      if (!t.image || t.image->empty()) Fail(path + ".path", "image not loaded");
    }
  }
};

}  // namespace

double GroundSpec::HeightAt(double x, double y) const {
  double z = height + slope[0] * x + slope[1] * y;
  for (const StepSpec& step : steps) {
    const double side =
        (x - step.point[0]) * step.direction[0] + (y - step.point[1]) * step.direction[1];
    if (side > 0.0) z += step.height;
  }
  return z;
}

void Scene::Check() const {
  const Checker c{source};
  // Ground.
  c.Texture(ground.texture, "ground.texture");
  for (int i = 0; i < 2; ++i) c.InRange(ground.slope[i], -10.0, 10.0, "ground.slope");
  c.Positive(ground.cell_size, "ground.cell_size");
  c.Area(ground.extent, "ground.extent");
  for (size_t i = 0; i < ground.steps.size(); ++i) {
    const StepSpec& s = ground.steps[i];
    const std::string path = "ground.steps[" + std::to_string(i) + "]";
    if (std::hypot(s.direction[0], s.direction[1]) == 0.0) c.Fail(path + ".direction", "must not be zero");
  }
  // Targets.
  for (size_t i = 0; i < targets.size(); ++i) {
    const std::string path = "targets[" + std::to_string(i) + "]";
    c.Positive(targets[i].size[0], path + ".size[0]");
    c.Positive(targets[i].size[1], path + ".size[1]");
    c.Texture(targets[i].texture, path + ".texture");
  }
  // Occluders.
  if (has_voxels) {
    const std::string p = "occluders.voxels";
    for (int i = 0; i < 3; ++i) {
      c.Positive(voxels.size[i], p + ".size[" + std::to_string(i) + "]");
      c.IntRange(voxels.grid[i], 1, 512, p + ".grid[" + std::to_string(i) + "]");
    }
    c.InRange(voxels.density, 0.0, 1.0, p + ".density", /*hi_open=*/true);
    c.Color(voxels.albedo, p + ".albedo");
    c.InRange(voxels.albedo_variation, 0.0, 1.0, p + ".albedo_variation");
  }
  if (has_trees) {
    const std::string p = "occluders.trees";
    c.Area(trees.area, p + ".area");
    c.Positive(trees.per_hectare, p + ".per_hectare");
    if (trees.per_hectare > 20000.0) c.Fail(p + ".per_hectare", "must be at most 20000");
    c.Range(trees.height, p + ".height");
    c.Range(trees.crown_radius, p + ".crown_radius");
    c.InRange(trees.crown_fraction, 0.0, 1.0, p + ".crown_fraction");
    c.Positive(trees.crown_fraction, p + ".crown_fraction");
    c.Positive(trees.trunk_radius, p + ".trunk_radius");
    c.Positive(trees.leaf_size, p + ".leaf_size");
    c.IntRange(trees.leaves_per_tree, 0, 100000, p + ".leaves_per_tree");
    c.Color(trees.leaf_albedo, p + ".leaf_albedo");
    c.Color(trees.trunk_albedo, p + ".trunk_albedo");
    c.InRange(trees.albedo_variation, 0.0, 1.0, p + ".albedo_variation");
  }
  // Camera.
  c.IntRange(camera.width, 1, 16384, "camera.width");
  c.IntRange(camera.height, 1, 16384, "camera.height");
  if (camera.lens != "pinhole" && camera.lens != "radtan" && camera.lens != "fisheye" &&
      camera.lens != "omnidir") {
    c.Fail("camera.lens", "\"" + camera.lens +
                              "\" is not a lens model (pinhole, radtan, fisheye or omnidir)");
  }
  const bool wide = camera.lens == "fisheye" || camera.lens == "omnidir";
  if (camera.fx > 0.0) {
    for (const auto& [value, name] : {std::pair{camera.fy, "camera.fy"}, {camera.cx, "camera.cx"},
                                      {camera.cy, "camera.cy"}}) {
      if (!std::isfinite(value)) c.Fail(name, "must be finite");
    }
    if (!std::isfinite(camera.fx)) c.Fail("camera.fx", "must be finite");
    if (!(camera.fy > 0.0)) c.Fail("camera.fy", "must be > 0");
  } else {
    c.InRange(camera.fov_deg, 0.0, wide ? 360.0 : 180.0, "camera.fov_deg", true);
    c.Positive(camera.fov_deg, "camera.fov_deg");
  }
  for (size_t i = 0; i < camera.distortion.size(); ++i) {
    const std::string path = "camera.distortion[" + std::to_string(i) + "]";
    if (!std::isfinite(camera.distortion[i])) c.Fail(path, "must be finite");
    if (camera.distortion[i] == 0.0) continue;
    if (camera.lens == "pinhole") c.Fail(path, "a pinhole lens has no distortion");
    if (camera.lens == "fisheye" && i == 4) c.Fail(path, "the fisheye model has k1..k4 only");
    if (camera.lens == "omnidir" && i == 4) c.Fail(path, "the omnidir model has k1, k2, p1, p2 only");
  }
  if (camera.lens == "omnidir") {
    c.InRange(camera.xi, 0.0, 1e3, "camera.xi");
  } else if (camera.xi != CameraSpec{}.xi && camera.xi != 0.0) {
    c.Fail("camera.xi", "only the omnidir lens has xi");
  }
  if (!std::isfinite(camera.skew)) c.Fail("camera.skew", "must be finite");
  if (camera.lens != "omnidir" && camera.skew != 0.0) {
    c.Fail("camera.skew", "only the omnidir lens has skew");
  }
  ViewLens(*this);  // the lens must be invertible and cover the field of view
  if (camera.channels != 1 && camera.channels != 3) c.Fail("camera.channels", "must be 1 or 3");
  if (camera.bit_depth != 8 && camera.bit_depth != 16 && camera.bit_depth != 32) {
    c.Fail("camera.bit_depth", "must be 8, 16 or 32");
  }
  c.IntRange(camera.samples_per_pixel, 1, 8, "camera.samples_per_pixel");
  // Sampling.
  if (sampling.positions.empty()) {
    c.Positive(sampling.altitude, "sampling.altitude");
    if (sampling.aperture_shape != "square" && sampling.aperture_shape != "disk") {
      c.Fail("sampling.aperture.shape", "must be \"square\" or \"disk\"");
    }
    c.InRange(sampling.aperture_diameter, 0.0, 1e5, "sampling.aperture.diameter");
    c.IntRange(sampling.grid, 1, 1000, "sampling.grid");
  }
  // Effects.
  if (effects.pose_noise) {
    c.InRange(effects.pose_noise_spec.position_sigma_cm, 0.0, 1e4,
              "effects.pose_noise.position_sigma_cm");
    c.InRange(effects.pose_noise_spec.rotation_sigma_deg, 0.0, 10.0,
              "effects.pose_noise.rotation_sigma_deg");
  }
  if (effects.sensor_noise) c.InRange(effects.sensor_noise_spec.sigma, 0.0, 1.0, "effects.sensor_noise.sigma");
  if (effects.sun) {
    c.Positive(effects.sun_spec.elevation_deg, "effects.sun.elevation_deg");
    c.InRange(effects.sun_spec.elevation_deg, 0.0, 90.0, "effects.sun.elevation_deg");
    c.InRange(effects.sun_spec.azimuth_deg, -360.0, 360.0, "effects.sun.azimuth_deg");
    c.InRange(effects.sun_spec.ambient, 0.0, 1.0, "effects.sun.ambient");
  }
  if (effects.thermal) {
    const ThermalSpec& t = effects.thermal_spec;
    c.InRange(t.ground, 0, 1, "effects.thermal.ground");
    c.InRange(t.targets, 0, 1, "effects.thermal.targets");
    c.InRange(t.voxels, 0, 1, "effects.thermal.voxels");
    c.InRange(t.leaves, 0, 1, "effects.thermal.leaves");
    c.InRange(t.trunks, 0, 1, "effects.thermal.trunks");
    c.InRange(t.texture_contrast, 0, 1, "effects.thermal.texture_contrast");
    c.InRange(t.sun_heating, 0, 1, "effects.thermal.sun_heating");
    if (camera.channels != 1) c.Fail("camera.channels", "must be 1 in thermal mode");
  }
  // Truth.
  if (truth.fov_deg != 0.0) {
    c.Positive(truth.fov_deg, "truth.fov_deg");
    c.InRange(truth.fov_deg, 0.0, 180.0, "truth.fov_deg", true);
  }
  c.IntRange(truth.width, 0, 16384, "truth.width");
  c.IntRange(truth.height, 0, 16384, "truth.height");

  // Cameras must be above the ground and outside the occluders.
  const std::vector<Vec3d> positions = ViewPositions(*this);
  std::vector<std::pair<std::string, Vec3d>> cameras;
  for (size_t i = 0; i < positions.size(); ++i) {
    cameras.emplace_back((sampling.positions.empty() ? "sampling (view " : "sampling.positions[") +
                             std::to_string(i) + (sampling.positions.empty() ? ")" : "]"),
                         positions[i]);
  }
  if (!std::isnan(truth.position[0])) {
    cameras.emplace_back("truth.position",
                         Vec3d(truth.position[0], truth.position[1], truth.position[2]));
  }
  for (const auto& [path, p] : cameras) {
    if (!std::isfinite(p.x) || !std::isfinite(p.y) || !std::isfinite(p.z)) c.Fail(path, "is not finite");
    const double ground_z = ground.HeightAt(p.x, p.y);
    if (!(p.z > ground_z)) {
      c.Fail(path, "camera at z = " + FormatNumber(p.z) + " m is not above the ground (z = " +
                       FormatNumber(ground_z) + " m there)");
    }
    if (has_voxels) {
      bool inside = true;
      for (int i = 0; i < 3; ++i) {
        inside = inside && std::abs(p[i] - voxels.center[i]) <= 0.5 * voxels.size[i];
      }
      if (inside) c.Fail(path, "camera is inside the voxel occluder volume (occluders.voxels)");
    }
    if (has_trees && p.z - ground_z <= trees.height[1]) {
      const auto& a = trees.area;
      const double margin = trees.crown_radius[1];
      const bool in_area = a == std::array<double, 4>{0, 0, 0, 0} ||
                           (p.x >= a[0] - margin && p.x <= a[2] + margin &&
                            p.y >= a[1] - margin && p.y <= a[3] + margin);
      if (in_area) {
        c.Fail(path, "camera is not above the trees (occluders.trees.height reaches " +
                         FormatNumber(trees.height[1]) + " m above the ground)");
      }
    }
  }
  if (positions.empty()) c.Fail("sampling", "no views (the disk aperture holds no grid point)");
}

LensCamera ViewLens(const Scene& scene) {
  const CameraSpec& c = scene.camera;
  const LensModel model = ParseLensModel(c.lens, scene.source + ": /camera/lens");
  if (c.fx > 0.0) {
    LensCamera lens;
    lens.model = model;
    lens.width = c.width;
    lens.height = c.height;
    lens.fx = c.fx;
    lens.fy = c.fy;
    lens.cx = c.cx;
    lens.cy = c.cy;
    if (!TraitsOf(model).pinhole) lens.distortion = c.distortion;
    if (TraitsOf(model).has_xi) {
      lens.xi = c.xi;
      lens.skew = c.skew;
    }
    lens.Finalize(scene.source + ": /camera");
    return lens;
  }
  return LensFromFov(model, c.width, c.height,
                     c.fov_deg, c.distortion, c.xi, scene.source + ": /camera");
}

std::vector<Vec3d> ViewPositions(const Scene& scene) {
  const SamplingSpec& s = scene.sampling;
  std::vector<Vec3d> positions;
  if (!s.positions.empty()) {
    for (const auto& p : s.positions) positions.emplace_back(p[0], p[1], p[2]);
    return positions;
  }
  const int n = std::max(1, s.grid);
  const double step = n > 1 ? s.aperture_diameter / (n - 1) : 0.0;
  const double half = 0.5 * s.aperture_diameter;
  for (int j = 0; j < n; ++j) {
    for (int i = 0; i < n; ++i) {
      // Row j = 0 is the northernmost (+y) row, so views read like an image from above.
      const double dx = n > 1 ? -half + i * step : 0.0;
      const double dy = n > 1 ? half - j * step : 0.0;
      if (s.aperture_shape == "disk" && std::hypot(dx, dy) > half * (1.0 + 1e-12)) continue;
      positions.emplace_back(s.center[0] + dx, s.center[1] + dy, s.altitude);
    }
  }
  return positions;
}

namespace {
Scene SceneFromJson(const json& root, const std::string& source, const std::string& base_dir);
}  // namespace

Scene ParseScene(const std::string& json_text, const std::string& source,
                 const std::string& base_dir) {
  const json root = ParseJsonText(json_text, source);
  return WithJsonErrorsNamed(source, [&] { return SceneFromJson(root, source, base_dir); });
}

namespace {

Scene SceneFromJson(const json& root, const std::string& source, const std::string& base_dir) {
  Scene scene;
  scene.source = source;
  Reader top(root, "", scene.source);
  top.String("format", "aos-scene");  // optional marker, any value is not allowed below
  if (top.Has("format") && root["format"] != "aos-scene") {
    top.Fail("format", "must be \"aos-scene\"");
  }
  top.Int("version", 1);
  if (top.Has("version") && root["version"] != 1) top.Fail("version", "must be 1");
  const int seed = top.Int("seed", 1);
  if (seed < 0) top.Fail("seed", "must be >= 0");
  scene.seed = static_cast<uint32_t>(seed);

  if (top.Has("ground")) {
    Reader r = top.Child("ground");
    GroundSpec& g = scene.ground;
    g.height = r.Number("height", g.height);
    g.slope = r.Numbers<2>("slope", g.slope);
    g.cell_size = r.Number("cell_size", g.cell_size);
    g.extent = r.Numbers<4>("extent", g.extent);
    if (r.Has("steps")) {
      const json& steps = r.Array("steps");
      for (size_t i = 0; i < steps.size(); ++i) {
        Reader s(steps[i], Join(r.path(), "steps") + "[" + std::to_string(i) + "]", scene.source);
        StepSpec step;
        step.point = s.Numbers<2>("point", step.point);
        step.direction = s.Numbers<2>("direction", step.direction);
        step.height = s.Number("height", step.height);
        s.Finish();
        g.steps.push_back(step);
      }
    }
    if (r.Has("texture")) g.texture = ReadTexture(r.Child("texture"), g.texture, base_dir);
    r.Finish();
  }
  if (top.Has("targets")) {
    const json& targets = top.Array("targets");
    for (size_t i = 0; i < targets.size(); ++i) {
      Reader r(targets[i], "targets[" + std::to_string(i) + "]", scene.source);
      TargetSpec t;
      t.texture = DefaultTargetTexture();
      t.center = Numbers2(r, "center", t.center);
      t.size = Numbers2(r, "size", t.size);
      t.rotation_deg = r.Number("rotation_deg", t.rotation_deg);
      t.texture.size = t.size;  // an image texture covers the target unless told otherwise
      if (r.Has("texture")) t.texture = ReadTexture(r.Child("texture"), t.texture, base_dir);
      r.Finish();
      scene.targets.push_back(t);
    }
  }
  if (top.Has("occluders")) {
    Reader occ = top.Child("occluders");
    if (occ.Has("voxels")) {
      Reader r = occ.Child("voxels");
      VoxelSpec& v = scene.voxels;
      scene.has_voxels = true;
      v.center = r.Numbers<3>("center", v.center);
      v.size = r.Numbers<3>("size", v.size);
      if (r.Has("grid")) {
        const json& grid = r.Get("grid");
        if (grid.is_number()) {
          const int n = r.IntOf(grid, Join(r.path(), "grid"));
          v.grid = {n, n, n};
        } else {
          if (!grid.is_array() || grid.size() != 3) {
            r.Fail(Join(r.path(), "grid"), "must be an integer or an array of 3 integers");
          }
          for (int i = 0; i < 3; ++i) {
            v.grid[i] = r.IntOf(grid[i], Join(r.path(), "grid") + "[" + std::to_string(i) + "]");
          }
        }
      }
      v.density = r.Number("density", v.density);
      v.albedo = r.Color("albedo", v.albedo);
      v.albedo_variation = r.Number("albedo_variation", v.albedo_variation);
      r.Finish();
    }
    if (occ.Has("trees")) {
      Reader r = occ.Child("trees");
      TreeSpec& t = scene.trees;
      scene.has_trees = true;
      t.area = r.Numbers<4>("area", t.area);
      t.per_hectare = r.Number("per_hectare", t.per_hectare);
      t.height = r.Numbers<2>("height", t.height);
      t.crown_radius = r.Numbers<2>("crown_radius", t.crown_radius);
      t.crown_fraction = r.Number("crown_fraction", t.crown_fraction);
      t.trunk_radius = r.Number("trunk_radius", t.trunk_radius);
      t.leaf_size = r.Number("leaf_size", t.leaf_size);
      t.leaves_per_tree = r.Int("leaves_per_tree", t.leaves_per_tree);
      t.leaf_albedo = r.Color("leaf_albedo", t.leaf_albedo);
      t.trunk_albedo = r.Color("trunk_albedo", t.trunk_albedo);
      t.albedo_variation = r.Number("albedo_variation", t.albedo_variation);
      r.Finish();
    }
    occ.Finish();
  }
  if (top.Has("camera")) {
    Reader r = top.Child("camera");
    CameraSpec& c = scene.camera;
    c.width = r.Int("width", c.width);
    c.height = r.Int("height", c.height);
    // The camera takes the fields of every aos camera (json_codec.h: model, width, height,
    // fov_deg or fx, fy, cx, cy, distortion, xi, skew) and the sensor's; "lens" is the scene
    // format's older name of "model".
    c.fov_deg = r.Number("fov_deg", c.fov_deg);
    if (r.Has("model") && r.Has("lens")) r.Fail(r.path(), "give model or lens (its older name), not both");
    c.lens = r.String("lens", c.lens);
    c.lens = r.String("model", c.lens);
    const bool has_intrinsic = r.Has("fx") || r.Has("fy") || r.Has("cx") || r.Has("cy");
    if (has_intrinsic) {
      if (r.Has("fov_deg")) r.Fail(r.path(), "give either fov_deg or fx, fy, cx, cy, not both");
      for (const char* key : {"fx", "fy", "cx", "cy"}) {
        if (!r.Has(key)) r.Fail(Join(r.path(), key), "missing (fx, fy, cx, cy go together)");
      }
      c.fx = r.Number("fx", 0.0);
      c.fy = r.Number("fy", 0.0);
      c.cx = r.Number("cx", 0.0);
      c.cy = r.Number("cy", 0.0);
      if (!(c.fx > 0.0)) r.Fail(Join(r.path(), "fx"), "must be > 0");
      if (!(c.fy > 0.0)) r.Fail(Join(r.path(), "fy"), "must be > 0");
    }
    c.skew = r.Number("skew", c.skew);
    if (r.Has("distortion")) {
      const json& values = r.Array("distortion");
      const std::string path = Join(r.path(), "distortion");
      if (values.empty() || values.size() > 5) r.Fail(path, "must be an array of 1 to 5 numbers");
      c.distortion = {0, 0, 0, 0, 0};
      for (size_t i = 0; i < values.size(); ++i) {
        c.distortion[i] = r.NumberOf(values[i], path + "[" + std::to_string(i) + "]");
      }
    }
    c.xi = r.Number("xi", c.xi);
    c.channels = r.Int("channels", c.channels);
    c.bit_depth = r.Int("bit_depth", c.bit_depth);
    c.samples_per_pixel = r.Int("samples_per_pixel", c.samples_per_pixel);
    r.Finish();
  }
  if (top.Has("sampling")) {
    Reader r = top.Child("sampling");
    SamplingSpec& s = scene.sampling;
    s.altitude = r.Number("altitude", s.altitude);
    s.grid = r.Int("grid", s.grid);
    s.center = Numbers2(r, "center", s.center);
    if (r.Has("aperture")) {
      Reader a = r.Child("aperture");
      s.aperture_shape = a.String("shape", s.aperture_shape);
      s.aperture_diameter = a.Number("diameter", s.aperture_diameter);
      a.Finish();
    }
    if (r.Has("positions")) {
      const json& positions = r.Array("positions");
      if (positions.empty()) r.Fail(Join(r.path(), "positions"), "is empty");
      for (size_t i = 0; i < positions.size(); ++i) {
        s.positions.push_back(r.NumbersOf<3>(
            positions[i], Join(r.path(), "positions") + "[" + std::to_string(i) + "]"));
      }
    }
    r.Finish();
  }
  if (top.Has("effects")) {
    Reader e = top.Child("effects");
    EffectsSpec& f = scene.effects;
    if (e.Has("pose_noise")) {
      Reader r = e.Child("pose_noise");
      f.pose_noise = true;
      f.pose_noise_spec.position_sigma_cm = r.Number("position_sigma_cm", 0.0);
      f.pose_noise_spec.rotation_sigma_deg = r.Number("rotation_sigma_deg", 0.0);
      r.Finish();
    }
    if (e.Has("sensor_noise")) {
      Reader r = e.Child("sensor_noise");
      f.sensor_noise = true;
      f.sensor_noise_spec.sigma = r.Number("sigma", 0.0);
      r.Finish();
    }
    if (e.Has("sun")) {
      Reader r = e.Child("sun");
      f.sun = true;
      f.sun_spec.azimuth_deg = r.Number("azimuth_deg", f.sun_spec.azimuth_deg);
      f.sun_spec.elevation_deg = r.Number("elevation_deg", f.sun_spec.elevation_deg);
      f.sun_spec.ambient = r.Number("ambient", f.sun_spec.ambient);
      r.Finish();
    }
    if (e.Has("thermal")) {
      Reader r = e.Child("thermal");
      ThermalSpec& t = f.thermal_spec;
      f.thermal = true;
      t.ground = r.Number("ground", t.ground);
      t.targets = r.Number("targets", t.targets);
      t.voxels = r.Number("voxels", t.voxels);
      t.leaves = r.Number("leaves", t.leaves);
      t.trunks = r.Number("trunks", t.trunks);
      t.texture_contrast = r.Number("texture_contrast", t.texture_contrast);
      t.sun_heating = r.Number("sun_heating", t.sun_heating);
      r.Finish();
    }
    if (e.Has("lens_distortion")) {
      e.Fail("effects.lens_distortion",
             "is not an effect: a lens is set by camera.lens, camera.distortion and camera.xi");
    }
    e.Finish();
  }
  if (top.Has("truth")) {
    Reader r = top.Child("truth");
    TruthSpec& t = scene.truth;
    if (r.Has("position")) t.position = r.Numbers<3>("position", t.position);
    t.fov_deg = r.Number("fov_deg", t.fov_deg);
    t.width = r.Int("width", t.width);
    t.height = r.Int("height", t.height);
    t.blocked_fraction = r.Bool("blocked_fraction", t.blocked_fraction);
    r.Finish();
  }
  top.Finish();
  scene.Check();
  return scene;
}

}  // namespace

Scene LoadScene(const std::string& path) {
  const std::string text = ReadTextFile(path);
  const fs::path base = fs::path(path).parent_path();
  return ParseScene(text, path, base.empty() ? "." : base.string());
}

namespace {

ojson ColorJson(const Rgb& c) {
  if (c[0] == c[1] && c[1] == c[2]) return c[0];
  return ojson::array({c[0], c[1], c[2]});
}

ojson TextureJson(const TextureSpec& t) {
  ojson j;
  j["type"] = TextureKindName(t.kind);
  switch (t.kind) {
    case TextureSpec::Kind::kConstant:
      j["color"] = ColorJson(t.color_a);
      break;
    case TextureSpec::Kind::kChecker:
    case TextureSpec::Kind::kNoise:
      j["square"] = t.square;
      j["colors"] = ojson::array({ColorJson(t.color_a), ColorJson(t.color_b)});
      if (t.kind == TextureSpec::Kind::kNoise) j["seed"] = t.seed;
      break;
    case TextureSpec::Kind::kChart:
      j["patch"] = t.patch;
      j["squares"] = t.squares;
      j["colors"] = ojson::array({ColorJson(t.color_a), ColorJson(t.color_b)});
      break;
    case TextureSpec::Kind::kImage:
      j["path"] = t.image_path;
      j["size"] = t.size;
      break;
  }
  return j;
}

}  // namespace

std::string SceneToJson(const Scene& s) {
  ojson j;
  j["format"] = "aos-scene";
  j["version"] = 1;
  j["seed"] = s.seed;
  ojson ground;
  ground["height"] = s.ground.height;
  ground["slope"] = s.ground.slope;
  ojson steps = ojson::array();
  for (const StepSpec& step : s.ground.steps) {
    steps.push_back({{"point", step.point}, {"direction", step.direction}, {"height", step.height}});
  }
  ground["steps"] = steps;
  ground["cell_size"] = s.ground.cell_size;
  ground["extent"] = s.ground.extent;
  ground["texture"] = TextureJson(s.ground.texture);
  j["ground"] = ground;
  ojson targets = ojson::array();
  for (const TargetSpec& t : s.targets) {
    targets.push_back({{"center", t.center},
                       {"size", t.size},
                       {"rotation_deg", t.rotation_deg},
                       {"texture", TextureJson(t.texture)}});
  }
  j["targets"] = targets;
  ojson occluders = ojson::object();
  if (s.has_voxels) {
    const VoxelSpec& v = s.voxels;
    occluders["voxels"] = {{"center", v.center},
                           {"size", v.size},
                           {"grid", v.grid},
                           {"density", v.density},
                           {"albedo", ColorJson(v.albedo)},
                           {"albedo_variation", v.albedo_variation}};
  }
  if (s.has_trees) {
    const TreeSpec& t = s.trees;
    occluders["trees"] = {{"area", t.area},
                          {"per_hectare", t.per_hectare},
                          {"height", t.height},
                          {"crown_radius", t.crown_radius},
                          {"crown_fraction", t.crown_fraction},
                          {"trunk_radius", t.trunk_radius},
                          {"leaf_size", t.leaf_size},
                          {"leaves_per_tree", t.leaves_per_tree},
                          {"leaf_albedo", ColorJson(t.leaf_albedo)},
                          {"trunk_albedo", ColorJson(t.trunk_albedo)},
                          {"albedo_variation", t.albedo_variation}};
  }
  j["occluders"] = occluders;
  const CameraSpec& c = s.camera;
  j["camera"] = {{"width", c.width},       {"height", c.height},
                 {"fov_deg", c.fov_deg},   {"lens", c.lens},
                 {"channels", c.channels}, {"bit_depth", c.bit_depth},
                 {"samples_per_pixel", c.samples_per_pixel}};
  if (c.fx > 0.0) {
    j["camera"].erase("fov_deg");
    j["camera"]["fx"] = c.fx;
    j["camera"]["fy"] = c.fy;
    j["camera"]["cx"] = c.cx;
    j["camera"]["cy"] = c.cy;
  }
  if (c.lens == "omnidir" && c.skew != 0.0) j["camera"]["skew"] = c.skew;
  if (c.lens != "pinhole") j["camera"]["distortion"] = c.distortion;
  if (c.lens == "omnidir") j["camera"]["xi"] = c.xi;
  ojson sampling;
  sampling["altitude"] = s.sampling.altitude;
  sampling["aperture"] = {{"shape", s.sampling.aperture_shape},
                          {"diameter", s.sampling.aperture_diameter}};
  sampling["grid"] = s.sampling.grid;
  sampling["center"] = s.sampling.center;
  if (!s.sampling.positions.empty()) sampling["positions"] = s.sampling.positions;
  j["sampling"] = sampling;
  ojson effects = ojson::object();
  const EffectsSpec& e = s.effects;
  if (e.pose_noise) {
    effects["pose_noise"] = {{"position_sigma_cm", e.pose_noise_spec.position_sigma_cm},
                             {"rotation_sigma_deg", e.pose_noise_spec.rotation_sigma_deg}};
  }
  if (e.sensor_noise) effects["sensor_noise"] = {{"sigma", e.sensor_noise_spec.sigma}};
  if (e.sun) {
    effects["sun"] = {{"azimuth_deg", e.sun_spec.azimuth_deg},
                      {"elevation_deg", e.sun_spec.elevation_deg},
                      {"ambient", e.sun_spec.ambient}};
  }
  if (e.thermal) {
    const ThermalSpec& t = e.thermal_spec;
    effects["thermal"] = {{"ground", t.ground},
                          {"targets", t.targets},
                          {"voxels", t.voxels},
                          {"leaves", t.leaves},
                          {"trunks", t.trunks},
                          {"texture_contrast", t.texture_contrast},
                          {"sun_heating", t.sun_heating}};
  }
  j["effects"] = effects;
  ojson truth;
  if (!std::isnan(s.truth.position[0])) truth["position"] = s.truth.position;
  truth["fov_deg"] = s.truth.fov_deg;
  truth["width"] = s.truth.width;
  truth["height"] = s.truth.height;
  truth["blocked_fraction"] = s.truth.blocked_fraction;
  j["truth"] = truth;
  return j.dump(2) + "\n";
}

Scene DefaultScene() {
  // scenes/forest_person.json, field for field (tests/cpp/scene_test.cpp checks they agree): a
  // red 0.6 x 1.8 m target (a person lying down) on a brown-green forest floor under 300
  // procedural trees per hectare (8-13 m tall, sparse 500-leaf crowns) that block about two
  // thirds of the views' rays to it; RGB views of 384 x 384 pixels, 11 x 11 over a 30 m square
  // from 30 m; no sun (shadows would darken the target the canopy already hides).
  Scene scene;
  scene.source = "<built-in default scene>";
  scene.seed = 5;
  scene.ground.texture.kind = TextureSpec::Kind::kNoise;
  scene.ground.texture.square = 0.4;
  scene.ground.texture.color_a = {0.16, 0.22, 0.08};
  scene.ground.texture.color_b = {0.42, 0.32, 0.18};
  TargetSpec target;
  target.center = {0.0, 0.0};
  target.size = {0.6, 1.8};
  target.rotation_deg = 25.0;
  target.texture = DefaultTargetTexture();
  target.texture.kind = TextureSpec::Kind::kConstant;
  target.texture.color_a = {0.95, 0.12, 0.04};
  scene.targets.push_back(target);
  scene.has_trees = true;
  scene.trees.area = {-40.0, -40.0, 40.0, 40.0};
  scene.trees.per_hectare = 300.0;
  scene.trees.height = {8.0, 13.0};
  scene.trees.crown_radius = {2.0, 3.5};
  scene.trees.crown_fraction = 0.6;
  scene.trees.leaf_size = 0.35;
  scene.trees.leaves_per_tree = 500;
  scene.camera.width = 384;
  scene.camera.height = 384;
  scene.camera.fov_deg = 60.0;
  scene.camera.channels = 3;
  scene.sampling.grid = 11;
  scene.sampling.aperture_diameter = 30.0;
  scene.sampling.altitude = 30.0;
  scene.truth.fov_deg = 20.0;
  scene.Check();
  return scene;
}

}  // namespace aos
