#include "aos/render/rectify.h"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <string>
#include <utility>

#include <opencv2/imgproc.hpp>

#include "aos/util/error.h"
#include "aos/util/memory.h"
#include "aos/util/math.h"

namespace aos {
namespace {


Mat3d RotationAbout(int axis, double degrees) {
  const double a = degrees * kPi / 180.0, c = std::cos(a), s = std::sin(a);
  switch (axis) {
    case 0: return MatFromRows(Vec3d(1, 0, 0), Vec3d(0, c, -s), Vec3d(0, s, c));
    case 1: return MatFromRows(Vec3d(c, 0, s), Vec3d(0, 1, 0), Vec3d(-s, 0, c));
    default: return MatFromRows(Vec3d(c, -s, 0), Vec3d(s, c, 0), Vec3d(0, 0, 1));
  }
}

int CvType(const Image& image) {
  const int channels = image.channels();
  switch (image.type()) {
    case PixelType::kU8: return CV_MAKETYPE(CV_8U, channels);
    case PixelType::kU16: return CV_MAKETYPE(CV_16U, channels);
    case PixelType::kF32: return CV_MAKETYPE(CV_32F, channels);
    default: ThrowInvalid("rectify: uint32 images cannot be rectified");
  }
}

}  // namespace

void RectifyOptions::Check() const {
  if (!(fov_deg > 0.0 && fov_deg < 180.0)) {
    ThrowInvalid("fov_deg: must be in (0, 180) degrees (got " + FormatNumber(fov_deg) + ")");
  }
  if (width < 0 || height < 0 || width > 65536 || height > 65536) {
    ThrowInvalid("width/height: must be 0 (the raw size) or 1..65536 pixels");
  }
  for (double angle : {yaw_deg, pitch_deg, roll_deg}) {
    if (!std::isfinite(angle)) ThrowInvalid("yaw_deg/pitch_deg/roll_deg: must be finite");
  }
}

void RectifiedSize(const LensCamera& lens, const RectifyOptions& options, int* width, int* height) {
  *width = options.width > 0 ? options.width : lens.width;
  *height = options.height > 0 ? options.height : lens.height;
}

uint64_t RectifierBytes(const LensCamera& lens, const RectifyOptions& options) {
  int width = 0, height = 0;
  RectifiedSize(lens, options, &width, &height);
  return SaturatingProduct({static_cast<uint64_t>(std::max(width, 0)),
                            static_cast<uint64_t>(std::max(height, 0)), 2 * sizeof(float)});
}

Rectifier MakeRectifier(const LensCamera& lens, const RectifyOptions& options,
                        ProgressSink* progress) {
  options.Check();
  LensCamera checked = lens;
  checked.Finalize("camera");
  Rectifier r;
  int width = 0, height = 0;
  RectifiedSize(lens, options, &width, &height);
  CheckMemoryBudget(RectifierBytes(lens, options),
                    "width/height: rectified frames of " + std::to_string(width) + "x" +
                        std::to_string(height) + " pixels",
                    "the resampling maps, 8 bytes a pixel");
  r.camera = PinholeCamera::FromFov(width, height, options.fov_deg);
  r.lens_from_rectified = RotationAbout(2, options.roll_deg) * RotationAbout(0, options.pitch_deg) *
                          RotationAbout(1, options.yaw_deg);
  r.map_x.resize(static_cast<size_t>(width) * height);
  r.map_y.resize(r.map_x.size());
  int64_t uncovered = 0;
  double worst_angle = 0.0;
  for (int y = 0; y < height; ++y) {
    if (ProgressCancelled(progress)) throw Cancelled();
    for (int x = 0; x < width; ++x) {
      const Vec3d ray = r.lens_from_rectified * r.camera.Unproject(Vec2d(x + 0.5, y + 0.5));
      Vec2d pixel;
      const bool inside = checked.Project(ray, &pixel) && pixel.x >= 0.0 &&
                          pixel.x <= lens.width && pixel.y >= 0.0 && pixel.y <= lens.height;
      if (!inside) {
        ++uncovered;
        worst_angle = std::max(worst_angle, std::acos(glm::normalize(ray).z) * 180.0 / kPi);
        pixel = Vec2d(-4.0, -4.0);  // outside the image and its interpolation taps: 0 (fill)
      }
      const size_t i = static_cast<size_t>(y) * width + x;
      r.map_x[i] = static_cast<float>(pixel.x - 0.5);  // OpenCV: pixel centres at integers
      r.map_y[i] = static_cast<float>(pixel.y - 0.5);
    }
  }
  if (uncovered > 0 && !options.fill) {
    ThrowInvalid("fov_deg: the lens does not cover the requested view: " +
                 std::to_string(uncovered) + " of " + std::to_string(r.map_x.size()) +
                 " rectified pixels fall outside the raw frame or the lens's valid field (rays up "
                 "to " + FormatNumber(worst_angle) + " degrees off the lens axis); use a smaller "
                 "fov_deg or another orientation, or fill to make those pixels black");
  }
  r.uncovered = uncovered;
  return r;
}

Image Rectify(const Rectifier& r, const Image& raw) {
  const int type = CvType(raw);
  const cv::Mat source(raw.height(), raw.width(), type, const_cast<void*>(raw.RawAt(0, 0)),
                       static_cast<size_t>(raw.row_stride()) * PixelTypeSize(raw.type()));
  const cv::Mat map_x(r.camera.height, r.camera.width, CV_32F, const_cast<float*>(r.map_x.data()));
  const cv::Mat map_y(r.camera.height, r.camera.width, CV_32F, const_cast<float*>(r.map_y.data()));
  Image out(r.camera.width, r.camera.height, raw.channels(), raw.type());
  cv::Mat target(out.height(), out.width(), type, out.RawAt(0, 0),
                 static_cast<size_t>(out.row_stride()) * PixelTypeSize(out.type()));
  cv::remap(source, target, map_x, map_y, cv::INTER_LINEAR, cv::BORDER_REPLICATE);
  if (r.uncovered == 0) return out;
  // fill: pixels the lens does not cover (mapped to -4.5, see MakeRectifier) are black.
  const size_t pixel_bytes = static_cast<size_t>(out.channels()) * PixelTypeSize(out.type());
  for (int y = 0; y < out.height(); ++y) {
    for (int x = 0; x < out.width(); ++x) {
      const size_t i = static_cast<size_t>(y) * out.width() + x;
      if (r.map_x[i] < -2.0f) std::memset(out.RawAt(x, y), 0, pixel_bytes);
    }
  }
  return out;
}

RectifyLightFieldResult RectifyLightField(const LightField& light_field,
                                          const RectifyOptions& options,
                                          ProgressSink* progress) {
  options.Check();
  RectifyLightFieldResult result;
  // Every field but the views (the crs was dropped); resampled premultiplied values and weights
  // stay premultiplied (lightfield/mask.h), so masked carries over too.
  result.light_field = EmptyLike(light_field);
  std::vector<std::pair<LensCamera, Rectifier>> rectifiers;  // one per distinct lens
  {
    // What the loop allocates, before it does: the maps of each distinct lens and every
    // rectified view (with its 1-pixel border).
    std::vector<const LensCamera*> lenses;
    uint64_t needed = 0;
    int lens_views = 0;
    const auto add = [&](uint64_t bytes) {
      needed = needed + bytes < needed ? UINT64_MAX : needed + bytes;
    };
    for (const View& view : light_field.views) {
      if (view.camera.IsPinhole()) continue;
      ++lens_views;
      if (std::none_of(lenses.begin(), lenses.end(),
                       [&](const LensCamera* lens) { return lens->SameParameters(view.camera); })) {
        lenses.push_back(&view.camera);
        add(RectifierBytes(view.camera, options));
      }
      int width = 0, height = 0;
      RectifiedSize(view.camera, options, &width, &height);
      add(SaturatingProduct({static_cast<uint64_t>(std::max(width, 0)) + 2,
                             static_cast<uint64_t>(std::max(height, 0)) + 2,
                             static_cast<uint64_t>(view.image.channels()),
                             PixelTypeSize(view.image.type())}));
    }
    CheckMemoryBudget(needed, "rectify: " + std::to_string(lens_views) + " lens views",
                      "the rectified views and the resampling maps of " +
                          std::to_string(lenses.size()) + " lens(es)");
  }
  ProgressStart(progress, "rectify", static_cast<int64_t>(light_field.views.size()));
  for (const View& view : light_field.views) {
    if (ProgressCancelled(progress)) throw Cancelled();
    if (view.camera.IsPinhole()) {
      result.light_field.views.push_back(view);
      ProgressAdvance(progress, 1);
      continue;
    }
    auto found = std::find_if(rectifiers.begin(), rectifiers.end(),
                              [&](const auto& entry) { return entry.first.SameParameters(view.camera); });
    if (found == rectifiers.end()) {
      try {
        rectifiers.emplace_back(view.camera, MakeRectifier(view.camera, options, progress));
      } catch (const std::invalid_argument& error) {
        ThrowInvalid(std::string(error.what()) + " (view " + view.name + ")");
      }
      found = rectifiers.end() - 1;
    }
    const Rectifier& rectifier = found->second;
    const Mat3d rectified_from_lens = glm::transpose(rectifier.lens_from_rectified);
    View rectified = MakeView(view.name, rectifier.camera,
                              Rigid3d{rectified_from_lens * view.cam_from_world.rotation,
                                      rectified_from_lens * view.cam_from_world.translation},
                              Rectify(rectifier, view.image));
    result.light_field.views.push_back(std::move(rectified));
    ++result.rectified_views;
    ProgressAdvance(progress, 1);
  }
  return result;
}

}  // namespace aos
