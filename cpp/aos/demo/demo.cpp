#include "aos/demo/demo.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <limits>
#include <sstream>

#include <nlohmann/json.hpp>

#include "aos/image/image_io.h"
#include "aos/render/integral.h"
#include "aos/render/merge.h"
#include "aos/util/error.h"
#include "aos/util/file_util.h"
#include "aos/util/math.h"
#include "aos/util/parallel.h"
#include "aos/util/timer.h"

namespace aos {
namespace {

namespace fs = std::filesystem;
using ojson = nlohmann::ordered_json;

constexpr double kInf = std::numeric_limits<double>::infinity();
// Surroundings percentile a target pixel must exceed to "stand out" (see demo.h).
constexpr double kStandoutPercentile = 0.99;
// Mask values of DemoResult::target_mask.
constexpr uint8_t kTargetPixel = 1;
constexpr uint8_t kSurroundingPixel = 2;

// Pixel class by the ground point each truth pixel sees (see demo.h): target, surroundings or
// neither.
Image TargetMask(const Scene& scene, const GroundTruth& truth, double margin) {
  const int width = truth.ground.width(), height = truth.ground.height();
  Image mask(width, height, 1, PixelType::kU8);
  const Rigid3d world_from_cam = truth.cam_from_world.Inverse();
  struct Frame {
    double cx, cy, cos_r, sin_r, half_w, half_d;
  };
  std::vector<Frame> frames;
  for (const TargetSpec& target : scene.targets) {
    const double r = DegToRad(target.rotation_deg);
    frames.push_back({target.center[0], target.center[1], std::cos(r), std::sin(r),
                      0.5 * target.size[0], 0.5 * target.size[1]});
  }
  for (int y = 0; y < height; ++y) {
    for (int x = 0; x < width; ++x) {
      const double depth = *truth.depth.At<float>(x, y);
      if (!(depth > 0)) continue;
      const Vec3d ray = truth.camera.Unproject(Vec2d(x + 0.5, y + 0.5));
      const Vec3d point = world_from_cam * (ray * depth);
      uint8_t value = 0;
      for (const Frame& f : frames) {
        const double dx = point.x - f.cx, dy = point.y - f.cy;
        const double u = std::abs(f.cos_r * dx + f.sin_r * dy);
        const double v = std::abs(-f.sin_r * dx + f.cos_r * dy);
        if (u <= f.half_w && v <= f.half_d) {
          value = kTargetPixel;
          break;
        }
        if (u <= f.half_w + margin && v <= f.half_d + margin) value = kSurroundingPixel;
      }
      *mask.At<uint8_t>(x, y) = value;
    }
  }
  return mask;
}

// Mean colour of the pixels of class `label`.
std::vector<double> MeanColour(const Image& image, const Image& mask, uint8_t label) {
  std::vector<double> sum(image.channels(), 0.0);
  int64_t n = 0;
  for (int y = 0; y < image.height(); ++y) {
    for (int x = 0; x < image.width(); ++x) {
      if (*mask.At<uint8_t>(x, y) != label) continue;
      for (int c = 0; c < image.channels(); ++c) sum[c] += image.Value(x, y, c);
      ++n;
    }
  }
  for (double& s : sum) s = n > 0 ? s / n : 0.0;
  return sum;
}

TargetVisibility Visibility(const Image& image, const Image* count, const Image& mask,
                            const std::vector<double>& direction) {
  TargetVisibility v;
  if (direction.empty()) return v;
  std::vector<double> target, surroundings;
  for (int y = 0; y < image.height(); ++y) {
    for (int x = 0; x < image.width(); ++x) {
      const uint8_t label = *mask.At<uint8_t>(x, y);
      if (label == 0) continue;
      if (count != nullptr && *count->At<uint32_t>(x, y) == 0) continue;
      double t = 0.0;
      for (int c = 0; c < image.channels(); ++c) t += direction[c] * image.Value(x, y, c);
      (label == kTargetPixel ? target : surroundings).push_back(t);
    }
  }
  v.target_pixels = static_cast<int64_t>(target.size());
  v.surrounding_pixels = static_cast<int64_t>(surroundings.size());
  if (target.empty() || surroundings.empty()) return v;
  v.has_target = true;
  auto mean_var = [](const std::vector<double>& values) {
    double mean = 0.0;
    for (double value : values) mean += value;
    mean /= values.size();
    double var = 0.0;
    for (double value : values) var += (value - mean) * (value - mean);
    return std::pair<double, double>(mean, var / values.size());
  };
  const auto [mean_t, var_t] = mean_var(target);
  const auto [mean_s, var_s] = mean_var(surroundings);
  const double noise = std::sqrt(0.5 * (var_t + var_s));
  // A flat target on a flat surrounding (no noise at all): the contrast is all signal; report it
  // against a noise of one hundredth of a unit rather than dividing by zero.
  v.contrast_to_noise = (mean_t - mean_s) / std::max(noise, 1e-2);
  const size_t k = std::min(surroundings.size() - 1,
                            static_cast<size_t>(kStandoutPercentile * surroundings.size()));
  std::nth_element(surroundings.begin(), surroundings.begin() + k, surroundings.end());
  const double threshold = surroundings[k];
  const auto above = std::count_if(target.begin(), target.end(),
                                   [&](double t) { return t > threshold; });
  v.standout_fraction = static_cast<double>(above) / target.size();
  return v;
}

std::string Fixed(double value, int digits) {
  if (std::isinf(value)) return value > 0 ? "inf" : "-inf";
  char text[64];
  std::snprintf(text, sizeof(text), "%.*f", digits, value);
  return text;
}

std::string HtmlEscape(const std::string& text) {
  std::string out;
  for (char c : text) {
    switch (c) {
      case '&': out += "&amp;"; break;
      case '<': out += "&lt;"; break;
      case '>': out += "&gt;"; break;
      case '"': out += "&quot;"; break;
      default: out += c;
    }
  }
  return out;
}

ojson VisibilityJson(const TargetVisibility& v) {
  ojson j;
  j["has_target"] = v.has_target;
  j["target_pixels"] = v.target_pixels;
  j["surrounding_pixels"] = v.surrounding_pixels;
  j["contrast_to_noise"] = v.contrast_to_noise;
  j["standout_fraction"] = v.standout_fraction;
  return j;
}

bool FloatViews(const DemoResult& result) {
  return result.simulation.truth.ground.type() == PixelType::kF32;
}

// Where the page finds the truth image (a PNG a browser shows).
std::string TruthPng(const DemoResult& result) {
  return FloatViews(result) ? "truth_ground.png" : "truth/ground.png";
}

// Shell-ready "--look-at ... --fov-deg ... --width ... --height ..." of the truth camera.
std::string TruthCameraFlags(const DemoResult& result) {
  const GroundTruth& truth = result.simulation.truth;
  // + 0.0 turns -0 (from the pose inversion) into 0 for the reader.
  const Vec3d c = truth.cam_from_world.Center() + Vec3d(0.0, 0.0, 0.0);
  const std::string x = FormatNumber(c.x), y = FormatNumber(c.y);
  return "--look-at " + x + "," + y + "," + FormatNumber(c.z) + "," + x + "," + y + "," +
         FormatNumber(result.ground_height + 0.0) + " --fov-deg " +
         FormatNumber(truth.camera.FovXDeg()) + " --width " + std::to_string(truth.camera.width) +
         " --height " + std::to_string(truth.camera.height);
}

// The demo flags of the options that differ from the defaults (threads aside: they change
// nothing in the output).
std::string DemoFlags(const DemoOptions& options) {
  const DemoOptions defaults;
  std::string flags;
  if (options.all_in_focus_slices != defaults.all_in_focus_slices) {
    flags += " --all-in-focus-slices " + std::to_string(options.all_in_focus_slices);
  }
  if (options.target_margin_m != defaults.target_margin_m) {
    flags += " --target-margin-m " + FormatNumber(options.target_margin_m);
  }
  return flags;
}

}  // namespace

void DemoOptions::Check() const {
  CheckThreadCount(num_threads);
  if (all_in_focus_slices < 0 || all_in_focus_slices > 1000) {
    ThrowInvalid("all_in_focus_slices: " + std::to_string(all_in_focus_slices) +
                 " is outside [0, 1000]");
  }
  if (!(target_margin_m > 0) || !std::isfinite(target_margin_m)) {
    ThrowInvalid("target_margin_m: " + FormatNumber(target_margin_m) +
                 " must be a finite number > 0");
  }
}

const DemoRender& DemoResult::Render(const std::string& name) const {
  for (const DemoRender& render : renders) {
    if (render.name == name) return render;
  }
  ThrowInvalid("demo: no render named '" + name + "'");
}

void CheckDemoFolder(const std::string& folder) { CheckOutputFolder(folder); }

DemoResult RunDemo(const Scene& scene, const DemoOptions& options, ProgressSink* progress) {
  options.Check();
  scene.Check();
  const Timer total;
  DemoResult result;
  result.scene = scene;
  result.options = options;
  SimulateOptions simulate;
  simulate.num_threads = options.num_threads;
  result.simulation = Simulate(scene, simulate, progress);
  result.seconds_simulation = total.Seconds();
  const GroundTruth& truth = result.simulation.truth;
  const LightField& light_field = result.simulation.light_field;

  // Focal planes: the ground, inside the occluders, and the top of the occluders.
  result.ground_height = truth.ground_height_at_center;
  if (scene.has_voxels) {
    result.occluder_height = scene.voxels.center[2];
    result.top_height = scene.voxels.center[2] + 0.5 * scene.voxels.size[2];
  } else if (scene.has_trees) {
    const double mean_height = 0.5 * (scene.trees.height[0] + scene.trees.height[1]);
    result.occluder_height =
        result.ground_height + mean_height * (1.0 - 0.5 * scene.trees.crown_fraction);
    result.top_height = result.ground_height + scene.trees.height[1];
  } else {
    result.occluder_height = result.ground_height;
    result.top_height = result.ground_height + 10.0;
  }

  // Target pixels and the colour direction that separates the target from its surroundings.
  result.target_mask = TargetMask(scene, truth, options.target_margin_m);
  std::vector<double> direction;
  {
    const std::vector<double> target = MeanColour(truth.ground, result.target_mask, kTargetPixel);
    const std::vector<double> around =
        MeanColour(truth.ground, result.target_mask, kSurroundingPixel);
    double norm = 0.0;
    for (size_t c = 0; c < target.size(); ++c) norm += (target[c] - around[c]) * (target[c] - around[c]);
    norm = std::sqrt(norm);
    // Less than a thousandth of the value range between target and surroundings: no contrast to
    // measure (a target painted like the ground).
    if (norm > 1e-3 * PixelTypeFullRange(truth.ground.type())) {
      for (size_t c = 0; c < target.size(); ++c) direction.push_back((target[c] - around[c]) / norm);
    }
  }
  result.truth_visibility = Visibility(truth.ground, nullptr, result.target_mask, direction);
  if (truth.has_blocked_fraction && result.truth_visibility.has_target) {
    double sum = 0.0;
    int64_t n = 0;
    for (int y = 0; y < result.target_mask.height(); ++y) {
      for (int x = 0; x < result.target_mask.width(); ++x) {
        if (*result.target_mask.At<uint8_t>(x, y) != kTargetPixel) continue;
        if (*truth.views_seeing.At<uint32_t>(x, y) == 0) continue;
        sum += *truth.blocked_fraction.At<float>(x, y);
        ++n;
      }
    }
    if (n > 0) result.target_blocked_fraction = sum / n;
  }

  // The renders, from the truth camera.
  IntegralOptions render;
  render.cam_from_world = truth.cam_from_world;
  render.fov_deg = truth.camera.FovXDeg();
  render.width = truth.camera.width;
  render.height = truth.camera.height;
  render.num_threads = options.num_threads;
  struct Job {
    const char* name;
    std::string title;
    double height;
    double radius;
  };
  std::vector<Job> jobs{
      {"single_view", "Single view (one photo from above)", result.ground_height, 0.0},
      {"integral_ground", "Integral image focused on the ground", result.ground_height, kInf}};
  if (scene.HasOccluders()) {
    jobs.push_back({"integral_occluders", "Integral image focused inside the canopy",
                    result.occluder_height, kInf});
  }
  for (const Job& job : jobs) {
    const Timer render_timer;
    render.focal_surface = FocalSurface::FromPlane(Plane::AtHeight(job.height));
    render.aperture_radius = job.radius;
    IntegralResult integral = RenderIntegral(light_field, render, progress);
    DemoRender out;
    out.name = job.name;
    out.title = job.title;
    out.focal_height = job.height;
    out.aperture_radius = job.radius;
    out.image = integral.image;
    out.count = integral.count;
    out.quality = CompareImages(out.image, truth.ground, &out.count, {});
    out.visibility = Visibility(out.image, &out.count, result.target_mask, direction);
    out.seconds = render_timer.Seconds();
    result.renders.push_back(std::move(out));
  }
  if (options.all_in_focus_slices > 0) {
    const Timer render_timer;
    AllInFocusOptions all;
    all.stack.render = render;
    // The slices' planes replace the focus (a stack refuses a plane it would ignore).
    all.stack.render.focal_surface = IntegralOptions().focal_surface;
    all.stack.render.aperture_radius = kInf;
    all.stack.first_plane = Plane::AtHeight(result.ground_height);
    all.stack.last_plane = Plane::AtHeight(result.top_height);
    all.stack.slices = options.all_in_focus_slices;
    all.merge.method = MergeMethod::kImproved;
    all.merge.num_threads = options.num_threads;
    MergeResult merged = RenderAllInFocus(light_field, all, progress);
    DemoRender out;
    out.name = "all_in_focus";
    out.title = "All-in-focus image (each pixel from its sharpest focal plane)";
    out.focal_height = result.ground_height;
    out.aperture_radius = kInf;
    out.image = merged.image;
    out.quality = CompareImages(out.image, truth.ground, nullptr, {});
    out.visibility = Visibility(out.image, nullptr, result.target_mask, direction);
    out.seconds = render_timer.Seconds();
    result.renders.push_back(std::move(out));
  }
  result.seconds_total = total.Seconds();
  return result;
}

std::string DemoSummaryJson(const DemoResult& result) {
  ojson j;
  j["scene"] = result.scene.source;
  j["views"] = result.simulation.light_field.views.size();
  j["ground_height"] = result.ground_height;
  j["occluder_height"] = result.occluder_height;
  j["top_height"] = result.top_height;
  j["target_blocked_fraction"] = result.target_blocked_fraction;
  j["truth"] = {{"file", TruthPng(result)},
                {"visibility", VisibilityJson(result.truth_visibility)}};
  ojson renders = ojson::array();
  for (const DemoRender& r : result.renders) {
    ojson e;
    e["name"] = r.name;
    e["file"] = r.name + ".png";
    e["title"] = r.title;
    e["focal_height"] = r.focal_height;
    e["aperture_radius"] = std::isinf(r.aperture_radius) ? ojson("inf") : ojson(r.aperture_radius);
    e["psnr_db"] = std::isinf(r.quality.psnr_db) ? ojson("inf") : ojson(r.quality.psnr_db);
    e["ssim"] = r.quality.ssim;
    e["color_ssim"] = r.quality.color_ssim;
    e["visibility"] = VisibilityJson(r.visibility);
    e["seconds"] = r.seconds;
    renders.push_back(e);
  }
  j["renders"] = renders;
  j["seconds_simulation"] = result.seconds_simulation;
  j["seconds_total"] = result.seconds_total;
  return j.dump(2) + "\n";
}

std::string DemoIndexHtml(const DemoResult& result) {
  const Scene& scene = result.scene;
  const GroundTruth& truth = result.simulation.truth;
  const size_t views = result.simulation.light_field.views.size();
  std::ostringstream h;
  h << "<!DOCTYPE html>\n<html lang=\"en\">\n<head>\n<meta charset=\"utf-8\">\n"
    << "<title>aos demo: seeing through a forest</title>\n<style>\n"
    << "body{font-family:sans-serif;max-width:1150px;margin:1.5em auto;padding:0 1em;"
       "color:#222;line-height:1.45}\n"
    << "h1{margin-bottom:.2em}\n.grid{display:flex;flex-wrap:wrap;gap:14px}\n"
    << "figure{margin:0;width:268px}\nfigure img{width:268px;height:auto;"
       "image-rendering:pixelated;border:1px solid #999;display:block}\n"
    << ".big figure,.big figure img{width:360px}\n"
    << ".lead{font-size:1.1em;background:#fff6e0;padding:.5em .8em;border-left:4px solid "
       "#e0a000}\n"
    << "figcaption{font-size:.85em;margin-top:.3em}\n.big figcaption b{font-size:1.05em}\n"
    << "table{border-collapse:collapse;margin:.5em 0;font-size:.92em}\n"
    << "td,th{border:1px solid #bbb;padding:.25em .6em;text-align:right}\n"
    << "th:first-child,td:first-child{text-align:left}\n"
    << "pre{background:#f4f4f4;padding:.6em;overflow-x:auto;font-size:.85em}\n"
    << ".note{color:#555;font-size:.9em}\n</style>\n</head>\n<body>\n";
  h << "<h1>Airborne Optical Sectioning: seeing through a forest</h1>\n";
  h << "<p>A drone photographs a forest from " << views
    << " positions spread over a wide area (the <i>synthetic aperture</i>). Any one photo shows "
       "mostly leaves. AOS averages, for every point of a chosen focal plane, the rays of all "
       "photos through it: points on that plane (here the forest floor) stay sharp, while "
       "branches and leaves above it land on different pixels in each photo and blur into a "
       "faint veil. What the canopy hides in every single photo becomes visible.</p>\n";
  const std::string target_words =
      scene.targets.empty()
          ? std::string("the ground")
          : std::string("the target (") + Fixed(scene.targets[0].size[0], 1) + " x " +
                Fixed(scene.targets[0].size[1], 1) + " m" +
                (scene.targets.size() > 1 ? ", and " + std::to_string(scene.targets.size() - 1) +
                                                " more"
                                          : std::string()) +
                ")";
  h << "<p>This folder holds a simulated flight (scene: <code>" << HtmlEscape(scene.source)
    << "</code>, every field in <a href=\"scene.json\">scene.json</a>): " << views
    << " views of " << scene.camera.width << " x " << scene.camera.height << " pixels from "
    << FormatNumber(scene.sampling.altitude) << " m, over a "
    << FormatNumber(scene.sampling.aperture_diameter) << " m " << scene.sampling.aperture_shape
    << " aperture. All images below are seen from the same virtual camera straight above "
    << target_words << ", " << truth.camera.width << " x " << truth.camera.height
    << " pixels.";
  if (result.target_blocked_fraction >= 0) {
    h << " The occluders block " << Fixed(100.0 * result.target_blocked_fraction, 0)
      << " % of the views' rays to the target.";
  }
  h << "</p>\n";

  // What to look for, in the figures' words.
  const DemoRender* single = nullptr;
  const DemoRender* integral = nullptr;
  for (const DemoRender& r : result.renders) {
    if (r.name == "single_view") single = &r;
    if (r.name == "integral_ground") integral = &r;
  }
  if (single != nullptr && integral != nullptr && single->visibility.has_target &&
      integral->visibility.has_target) {
    h << "<p class=\"lead\">Look for the target in the centre of each image. In the single "
         "view only "
      << Fixed(100.0 * single->visibility.standout_fraction, 0)
      << " % of its pixels stand out from the ground around it; in the integral image focused "
         "on the ground, "
      << Fixed(100.0 * integral->visibility.standout_fraction, 0) << " % do.</p>\n";
  }

  // The images.
  auto figure = [&](const std::string& file, const std::string& title, const std::string& text) {
    h << "<figure><a href=\"" << file << "\"><img src=\"" << file << "\" alt=\""
      << HtmlEscape(title) << "\"></a><figcaption><b>" << HtmlEscape(title) << "</b><br>" << text
      << "</figcaption></figure>\n";
  };
  auto text_of = [&](const DemoRender& r) -> std::string {
    if (r.name == "single_view") {
      return "One photo, from straight above: what a normal camera sees. The canopy hides "
             "most of the forest floor.";
    }
    if (r.name == "integral_ground") {
      return "All " + std::to_string(views) + " photos averaged, focused on the ground (z = " +
             Fixed(r.focal_height, 2) + " m): the leaves blur away and the ground shows.";
    }
    if (r.name == "integral_occluders") {
      return "The same photos focused at z = " + Fixed(r.focal_height, 2) +
             " m, inside the canopy: now the leaves there are sharp and the ground blurs.";
    }
    if (r.name == "all_in_focus") {
      return "A focal stack of " + std::to_string(result.options.all_in_focus_slices) +
             " planes from z = " + Fixed(result.ground_height, 2) + " to " +
             Fixed(result.top_height, 2) +
             " m, merged: each pixel from the plane where it is sharpest (canopy where it is "
             "dense, ground in between).";
    }
    return "";
  };
  h << "<div class=\"grid big\">\n";
  for (const DemoRender& r : result.renders) {
    if (r.name == "single_view" || r.name == "integral_ground") figure(r.name + ".png", r.title, text_of(r));
  }
  figure(TruthPng(result), "Ground truth",
         "The forest floor with every tree removed (simulated): what the integral image should "
         "approach.");
  h << "</div>\n<div class=\"grid\" style=\"margin-top:14px\">\n";
  for (const DemoRender& r : result.renders) {
    if (r.name != "single_view" && r.name != "integral_ground") figure(r.name + ".png", r.title, text_of(r));
  }
  h << "</div>\n";

  // The figures.
  h << "<h2>Figures</h2>\n<table>\n<tr><th>image</th><th>target stands out</th>"
       "<th>target contrast / noise</th><th>PSNR (dB)</th><th>SSIM</th><th>colour SSIM</th>"
       "</tr>\n";
  auto vis_cells = [&](const TargetVisibility& v) {
    if (!v.has_target) return std::string("<td>&ndash;</td><td>&ndash;</td>");
    return "<td>" + Fixed(100.0 * v.standout_fraction, 0) + " %</td><td>" +
           Fixed(v.contrast_to_noise, 2) + "</td>";
  };
  for (const DemoRender& r : result.renders) {
    h << "<tr><td><a href=\"" << r.name << ".png\">" << HtmlEscape(r.title) << "</a></td>"
      << vis_cells(r.visibility) << "<td>" << Fixed(r.quality.psnr_db, 2) << "</td><td>"
      << Fixed(r.quality.ssim, 3) << "</td><td>" << Fixed(r.quality.color_ssim, 3)
      << "</td></tr>\n";
  }
  h << "<tr><td><a href=\"" << TruthPng(result) << "\">Ground truth</a></td>"
    << vis_cells(result.truth_visibility) << "<td>&ndash;</td><td>1</td><td>1</td></tr>\n";
  h << "</table>\n<p class=\"note\"><b>Target stands out</b>: the share of the target's pixels "
       "that look more like the target than 99 % of the ground within "
    << FormatNumber(result.options.target_margin_m)
    << " m around it (its colour projected on the colour difference between target and ground "
       "in the truth). <b>Contrast / noise</b>: the difference of the mean of that projection "
       "over the target and over its surroundings, divided by their pooled standard deviation. "
       "PSNR and SSIM compare each image with the ground truth (over the pixels it covers; "
       "definitions in docs/metrics.md). The same figures are in <a href=\"demo.json\">"
       "demo.json</a>.</p>\n";

  // Reproduce.
  const std::string camera = TruthCameraFlags(result);
  h << "<h2>Reproduce</h2>\n<p>From this folder (each command writes a new file or folder):</p>\n"
    << "<pre>aos-render demo --scene scene.json" << DemoFlags(result.options)
    << " -o ../aos-demo-again\n"
    << "aos-render simulate scene.json -o ../simulation\n"
    << "aos-render integral lightfield.json " << camera << " \\\n    --focal-height "
    << FormatNumber(result.ground_height) << " --aperture-radius 0 -o ../single_view.png\n"
    << "aos-render integral lightfield.json " << camera << " \\\n    --focal-height "
    << FormatNumber(result.ground_height) << " -o ../integral_ground.png\n";
  if (scene.HasOccluders()) {
    h << "aos-render integral lightfield.json " << camera << " \\\n    --focal-height "
      << FormatNumber(result.occluder_height) << " -o ../integral_occluders.png\n";
  }
  if (result.options.all_in_focus_slices > 0) {
    h << "aos-render allinfocus lightfield.json " << camera << " \\\n    --first-plane "
      << FormatNumber(result.ground_height) << " --last-plane " << FormatNumber(result.top_height)
      << " --slices " << result.options.all_in_focus_slices << " -o ../all_in_focus\n";
  }
  h << "aos-render metrics ../integral_ground.png " << TruthPng(result) << "</pre>\n"
    << "<p>or from Python:</p>\n<pre>import aos\n"
    << "result = aos.run_demo(aos.load_scene(\"scene.json\"))\n"
    << "aos.write_demo(result, \"../aos-demo-again\")</pre>\n"
    << "<p class=\"note\">Files: <a href=\"lightfield.json\">lightfield.json</a> (the views "
       "and their poses; images in views/), <a href=\"lightfield_true.json\">"
       "lightfield_true.json</a> (true poses), <a href=\"truth/truth.json\">truth/truth.json"
       "</a> (the truth camera and simulation counters), truth/ (ground truth images).</p>\n";
  h << "</body>\n</html>\n";
  return h.str();
}

std::vector<std::string> WriteDemo(const DemoResult& result, const std::string& folder) {
  if (result.renders.empty()) ThrowInvalid("WriteDemo: the result holds no renders");
  PendingFolder pending(folder);
  const fs::path temp = pending.TempPath();
  // WriteSimulation fills the (empty) temporary folder atomically itself.
  WriteSimulation(result.simulation, result.scene, temp.string());
  const PixelType units = result.simulation.truth.ground.type();
  WriteImageOptions write;
  write.units = units;
  for (const DemoRender& r : result.renders) {
    write.description = "aos demo: " + r.title;
    WriteImage((temp / (r.name + ".png")).string(), r.image, write);
  }
  if (FloatViews(result)) {
    write.description = "aos demo: ground truth";
    WriteImage((temp / "truth_ground.png").string(), result.simulation.truth.ground, write);
  }
  WriteTextFileAtomic((temp / "demo.json").string(), DemoSummaryJson(result));
  WriteTextFileAtomic((temp / "index.html").string(), DemoIndexHtml(result));
  std::vector<std::string> files;
  for (const auto& entry : fs::recursive_directory_iterator(temp)) {
    if (entry.is_regular_file()) files.push_back(fs::relative(entry.path(), temp).generic_string());
  }
  std::sort(files.begin(), files.end());
  pending.Commit();
  return files;
}

}  // namespace aos
