#include "aos/lightfield/formats.h"
#include "aos/util/error.h"
namespace aos {
// PLACEHOLDER: being written.
void LoadOptions::Check() const {}
LoadResult LoadLightField(const std::string&, const LoadOptions&, ProgressSink*) { ThrowInvalid("not implemented"); }
void WriteLightField(const std::string&, const LightField&, const WriteLightFieldOptions&) { ThrowInvalid("not implemented"); }
double ParseNumberText(const std::string&, const std::string&) { ThrowInvalid("not implemented"); }
}  // namespace aos
