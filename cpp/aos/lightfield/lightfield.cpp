#include "aos/lightfield/lightfield.h"

#include <cmath>

#include "aos/util/error.h"

namespace aos {

size_t LightField::ImageBytes() const {
  size_t bytes = 0;
  for (const View& view : views) bytes += view.image.PixelBytes();
  return bytes;
}

void CheckView(const View& view, const std::string& where) {
  view.camera.Pinhole().Check(where);
  if (view.camera.model != LensModel::kPinhole && !(view.camera.theta_max > 0.0)) {
    ThrowInvalid(Where(where, "camera: the lens's valid field is not set (LensCamera::Finalize)"));
  }
  if (auto problem = DescribeInvalidRigid(view.cam_from_world)) {
    ThrowInvalid(Where(where, "cam_from_world: " + *problem));
  }
  if (view.image.empty()) ThrowInvalid(Where(where, "image: no pixels (image not loaded)"));
  if (view.image.width() != view.camera.width || view.image.height() != view.camera.height) {
    ThrowInvalid(Where(where, "image is " + std::to_string(view.image.width()) + "x" +
                                  std::to_string(view.image.height()) + " but the camera says " +
                                  std::to_string(view.camera.width) + "x" +
                                  std::to_string(view.camera.height)));
  }
  if (view.image.border() < 1) ThrowInvalid(Where(where, "image: needs a border of 1 pixel"));
  // Sample positions are single-precision floats in the inner loops: keep them exact to well
  // below a pixel.
  constexpr int kMaxSide = 1 << 22;
  if (view.image.width() > kMaxSide || view.image.height() > kMaxSide) {
    ThrowInvalid(Where(where, "image: wider or taller than 4194304 pixels"));
  }
  if (view.image.type() == PixelType::kU32) {
    ThrowInvalid(Where(where, "image: uint32 views are not supported (use 8/16-bit or float)"));
  }
}

static std::string ViewLabel(const std::string& where, size_t index, const View& view) {
  std::string label = where + ": view " + std::to_string(index);
  if (!view.name.empty()) label += " (" + view.name + ")";
  return label;
}

void CheckLightField(const LightField& light_field, const std::string& where) {
  for (int i = 0; i < 3; ++i) {
    if (!std::isfinite(light_field.origin[i])) ThrowInvalid(Where(where, "origin is not finite"));
  }
  for (size_t i = 0; i < light_field.views.size(); ++i) {
    const View& view = light_field.views[i];
    CheckView(view, ViewLabel(where, i, view));
    if (view.image.channels() != light_field.views[0].image.channels()) {
      ThrowInvalid(ViewLabel(where, i, view) + ": image has " +
                   std::to_string(view.image.channels()) + " channels but view 0 has " +
                   std::to_string(light_field.views[0].image.channels()));
    }
  }
}

View MakeView(std::string name, const LensCamera& camera, const Rigid3d& cam_from_world,
              Image image, std::string image_path) {
  View view;
  view.name = std::move(name);
  view.image_path = std::move(image_path);
  view.camera = camera;
  view.cam_from_world = cam_from_world;
  if (!image.empty() && image.border() < 1) {
    Image bordered(image.width(), image.height(), image.channels(), image.type(), 1);
    bordered.CopyFrom(image.RawAt(0, 0), image.row_stride());
    image = std::move(bordered);
  }
  view.image = std::move(image);
  const std::string where = view.name.empty() ? std::string("view") : "view " + view.name;
  view.camera.Pinhole().Check(where);
  if (!(view.camera.theta_max > 0.0)) view.camera.Finalize(Where(where, "camera"));
  CheckView(view, where);
  if (auto problem = DescribeNonFinite(view.image)) ThrowInvalid(Where(where, "image: " + *problem));
  return view;
}

View MakeView(std::string name, const PinholeCamera& camera, const Rigid3d& cam_from_world,
              Image image, std::string image_path) {
  const std::string where = name.empty() ? std::string("view") : "view " + name;
  camera.Check(where);
  return MakeView(std::move(name), LensCamera::FromPinhole(camera), cam_from_world,
                  std::move(image), std::move(image_path));
}

}  // namespace aos
