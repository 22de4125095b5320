#include "aos/render/integral.h"
#include "aos/util/error.h"
namespace aos {
// PLACEHOLDER: being written.
IntegralResult RenderIntegral(const LightField&, const IntegralOptions&, ProgressSink*) {
  ThrowInvalid("RenderIntegral: not implemented yet");
}
PinholeCamera VirtualCamera(const IntegralOptions& o) { return PinholeCamera::FromFov(o.width, o.height, o.fov_deg); }
void IntegralOptions::Check(int) const {}
}  // namespace aos
