#pragma once
// Scene descriptions for the occlusion simulator (docs/scenes.md has the file format with
// examples; scenes/ holds example files).
//
// A scene is: a ground (a plane, optionally tilted, or a height field made of slopes and steps)
// with a texture; targets lying on the ground; optional occluders (a random voxel volume and/or
// procedural trees); a nadir-looking camera (pinhole or a lens model) and where it takes its
// views; optional effects; and the virtual camera whose ground truth is written. Frames: the
// local world frame of the light field, z up, metres; degrees only in fields named *_deg.
//
// Only what a scene names is simulated: an absent "occluders" entry means no occluder geometry,
// an absent effect means that stage never runs (see simulator.h).
//
// Parsing is strict: unknown keys, wrong types and out-of-range values throw
// std::invalid_argument naming the file and the key path ("scene.json: occluders.voxels.density:
// 1.2 is outside [0, 1)").
#include <array>
#include <cmath>
#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "aos/geometry/lens.h"
#include "aos/geometry/rigid.h"
#include "aos/image/image.h"

namespace aos {

using Rgb = std::array<double, 3>;  // linear values in [0, 1]

// A surface pattern, evaluated at 2-D coordinates in metres (ground: world x, y; target: its own
// frame with the origin at its lower-left corner).
struct TextureSpec {
  enum class Kind {
    kConstant,  // `color_a` everywhere
    kChecker,   // squares of side `square` alternating color_a / color_b
    kChart,     // multi-resolution checkerboard chart (paper Fig. A2): patches of side `patch`;
                // patch (i, j) = (floor(x / patch), floor(y / patch)) uses squares[(i + j) mod n]
    kNoise,     // smooth value noise between color_a and color_b with feature size `square`
    kImage,     // an image file stretched over `size` metres (tiled beyond it)
  };
  Kind kind = Kind::kChart;
  Rgb color_a{0.9, 0.9, 0.9};
  Rgb color_b{0.1, 0.1, 0.1};
  double square = 1.0;                                 // metres (> 0)
  double patch = 4.0;                                  // chart patch side, metres (> 0)
  std::vector<double> squares{1.0, 0.5, 0.25, 0.125};  // chart square sizes, metres (> 0 each)
  std::string image_path;                              // kImage: file (resolved, absolute)
  std::array<double, 2> size{1.0, 1.0};                // kImage: metres covered by the image
                                                       // (on a target: the target's size)
  uint32_t seed = 0;                                   // kNoise: pattern seed
  std::shared_ptr<const Image> image;                  // kImage: decoded pixels (set by parser)
};

struct StepSpec {
  std::array<double, 2> point{0.0, 0.0};      // a point on the step's edge (x, y), metres
  std::array<double, 2> direction{1.0, 0.0};  // the ground rises by `height` on this side
  double height = 0.5;                        // metres (may be negative)
};

struct GroundSpec {
  double height = 0.0;                  // z at x = y = 0, metres
  std::array<double, 2> slope{0, 0};    // dz/dx, dz/dy (rise per metre)
  std::vector<StepSpec> steps;          // makes the ground a height field (Embree grid)
  double cell_size = 0.05;              // height-field grid spacing, metres (> 0)
  // Height-field extent [xmin, ymin, xmax, ymax], metres; all zero = the views' footprint.
  std::array<double, 4> extent{0, 0, 0, 0};
  TextureSpec texture;
  bool IsHeightField() const { return !steps.empty(); }
  // The ground height at (x, y) (the analytic surface; a height field is sampled from this).
  double HeightAt(double x, double y) const;
};

struct TargetSpec {
  std::array<double, 2> center{0.0, 0.0};  // (x, y), metres
  std::array<double, 2> size{2.4, 0.8};    // width along the rotated x axis, depth, metres (> 0)
  double rotation_deg = 0.0;               // about z, counter-clockwise from +x
  TextureSpec texture;                     // in target coordinates (metres from its corner)
};

struct VoxelSpec {
  std::array<double, 3> center{0.0, 0.0, 6.0};  // box centre, metres
  std::array<double, 3> size{10.0, 10.0, 10.0};  // box size, metres (> 0)
  std::array<int, 3> grid{100, 100, 100};        // cells per axis, 1..512
  // Fraction of nadir rays through the box that hit a voxel, [0, 1). Each cell is occupied
  // independently with probability 1 - (1 - density)^(1 / grid_z), so a column of grid_z cells
  // is empty with probability 1 - density.
  double density = 0.5;
  Rgb albedo{0.25, 0.45, 0.15};
  double albedo_variation = 0.3;  // per-voxel relative brightness spread, [0, 1]
};

struct TreeSpec {
  // Area where trunks stand [xmin, ymin, xmax, ymax], metres; all zero = the views' footprint.
  std::array<double, 4> area{0, 0, 0, 0};
  double per_hectare = 300.0;                // trees per 10,000 m^2 (> 0)
  std::array<double, 2> height{8.0, 14.0};   // range of tree heights, metres
  std::array<double, 2> crown_radius{1.5, 3.0};  // range of crown radii, metres
  double crown_fraction = 0.6;               // upper fraction of the height that is crown, (0, 1]
  double trunk_radius = 0.15;                // metres (> 0)
  double leaf_size = 0.3;                    // side of a square leaf, metres (> 0)
  int leaves_per_tree = 1500;                // >= 0
  Rgb leaf_albedo{0.2, 0.45, 0.15};
  Rgb trunk_albedo{0.35, 0.25, 0.15};
  double albedo_variation = 0.3;             // per-leaf relative brightness spread, [0, 1]
};

struct CameraSpec {
  int width = 512;          // pixels, 1..16384
  int height = 512;
  // Horizontal field of view across the image centre, from the lens's radial mapping (tangential
  // terms ignored): (0, 180) for "pinhole"/"radtan", (0, 360) for "fisheye"/"omnidir", and
  // inside the lens's valid field. Square pixels, principal point at the image centre.
  double fov_deg = 80.0;
  // "pinhole", "radtan", "fisheye" (equidistant) or "omnidir" (Mei), as in geometry/lens.h.
  std::string lens = "pinhole";
  // The lens's distortion (lens.h order): radtan {k1, k2, p1, p2, k3}, fisheye {k1..k4},
  // omnidir {k1, k2, p1, p2}; all zero for a pinhole.
  std::array<double, 5> distortion{0, 0, 0, 0, 0};
  double xi = 1.0;          // omnidir only, >= 0
  // Explicit intrinsics instead of fov_deg (the shape every aos camera has: a camera file's
  // fx, fy, cx, cy, pixels, with the pixel convention of lens.h); fx = 0 means "from fov_deg".
  double fx = 0.0;
  double fy = 0.0;
  double cx = 0.0;
  double cy = 0.0;
  double skew = 0.0;        // omnidir only
  int channels = 1;         // 1 (grey) or 3 (RGB)
  int bit_depth = 8;        // 8, 16 (integer) or 32 (float) views
  int samples_per_pixel = 1;  // n: an n x n stratified grid of rays per pixel, 1..8
};

struct SamplingSpec {
  double altitude = 20.0;                // camera height above z = 0, metres
  std::string aperture_shape = "square"; // "square" or "disk"
  double aperture_diameter = 30.0;       // side (square) or diameter (disk), metres (>= 0)
  int grid = 9;                          // views per side (grid x grid, cut to the disk)
  std::array<double, 2> center{0.0, 0.0};
  // Explicit camera centres (x, y, z); when given, replaces the grid.
  std::vector<std::array<double, 3>> positions;
};

struct PoseNoiseSpec {
  double position_sigma_cm = 0.0;   // per axis, centimetres
  double rotation_sigma_deg = 0.0;  // per axis (small rotation), degrees
};

struct SensorNoiseSpec {
  double sigma = 0.0;  // additive Gaussian, in [0, 1] units of the pixel range
};

struct SunSpec {
  double azimuth_deg = 135.0;   // from +x towards +y
  double elevation_deg = 45.0;  // above the horizon, (0, 90]
  double ambient = 0.3;         // share of light that is not direct sun (no shadow), [0, 1]
};

struct ThermalSpec {
  // Emission of each material, [0, 1] of the pixel range (replaces albedo and textures).
  double ground = 0.35;
  double targets = 0.9;
  double voxels = 0.5;
  double leaves = 0.5;
  double trunks = 0.45;
  // How much the ground/target textures modulate emission (0 = flat), [0, 1].
  double texture_contrast = 0.0;
  // Extra emission of a sunlit surface facing the sun (only with a sun), [0, 1].
  double sun_heating = 0.15;
};

struct EffectsSpec {
  bool pose_noise = false;
  PoseNoiseSpec pose_noise_spec;
  bool sensor_noise = false;
  SensorNoiseSpec sensor_noise_spec;
  bool sun = false;
  SunSpec sun_spec;
  bool thermal = false;
  ThermalSpec thermal_spec;
};

struct TruthSpec {
  // Virtual camera centre; unset (NaN) = the sampling centre at the mean view altitude.
  std::array<double, 3> position{std::nan(""), std::nan(""), std::nan("")};
  // Horizontal, (0, 180); 0 = the camera's, at most 100 degrees for a fisheye or omnidir camera
  // (the truth camera is a pinhole).
  double fov_deg = 0.0;
  int width = 0;          // 0 = the camera's
  int height = 0;
  // Per pixel, the fraction of the views seeing the ground point whose ray to it is blocked
  // (one ray per seeing view and pixel when anything can block: occluders or a height field).
  bool blocked_fraction = true;
};

struct Scene {
  std::string source;  // file name (for messages), "<built-in default>" or "<json>"
  uint32_t seed = 1;
  GroundSpec ground;
  std::vector<TargetSpec> targets;
  bool has_voxels = false;
  VoxelSpec voxels;
  bool has_trees = false;
  TreeSpec trees;
  CameraSpec camera;
  SamplingSpec sampling;
  EffectsSpec effects;
  TruthSpec truth;

  bool HasOccluders() const { return has_voxels || has_trees; }
  // Throws std::invalid_argument "<source>: <key path>: <reason>" for an invalid value.
  void Check() const;
};

// Parses scene JSON. Relative image paths are resolved against `base_dir`; images are decoded.
Scene ParseScene(const std::string& json_text, const std::string& source,
                 const std::string& base_dir = ".");
// Reads and parses a scene file.
Scene LoadScene(const std::string& path);
// The scene as JSON with every field written out (what was simulated; parses back equal).
std::string SceneToJson(const Scene& scene);

// The built-in default scene of `aos-render demo` (the same as scenes/forest_person.json): a red
// 0.6 x 1.8 m target on a noise-textured forest floor under procedural trees that block about
// two thirds of the views' rays to it, RGB, 11 x 11 views of 384 x 384 over a 30 m aperture at
// 30 m, a 20-degree truth camera.
Scene DefaultScene();

// The views' lens model from scene.camera (focal length from fov_deg, see CameraSpec). Throws
// std::invalid_argument "<source>: camera.<field>: <reason>" for a lens that is not invertible
// over the field of view.
LensCamera ViewLens(const Scene& scene);

// The camera centres of the views (true positions) in view order.
std::vector<Vec3d> ViewPositions(const Scene& scene);

}  // namespace aos
