#include "aos/sim/default_scene.h"
#include "aos/util/error.h"
namespace aos {
// PLACEHOLDER: being written.
Image RenderSyntheticView(const SyntheticScene&, const PinholeCamera&, const Rigid3d&, PixelType) { ThrowInvalid("not implemented"); }
void DefaultSceneOptions::Check() const {}
SyntheticScene MakeDefaultScene(const DefaultSceneOptions&) { ThrowInvalid("not implemented"); }
LightField MakeDefaultLightField(const DefaultSceneOptions&) { ThrowInvalid("not implemented"); }
Rigid3d NadirCamFromWorld(const Vec3d&) { return {}; }
}  // namespace aos
