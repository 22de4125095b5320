// libFuzzer harness: simulator scene files (aos::LoadScene, sim/scene.h). Image textures may
// name the fixture texture.png (fuzz_util.h).
//
// Beyond the error contract, an accepted scene must survive its own round trip: SceneToJson is
// documented to parse back equal, so ParseScene refusing that text is a finding too; ViewLens and
// ViewPositions (what the simulator calls next) may only throw std::invalid_argument.
#include <cstddef>
#include <cstdint>
#include <string>

#include "aos/sim/scene.h"
#include "fuzz_util.h"

extern "C" int LLVMFuzzerInitialize(int*, char***) {
  aos_fuzz::Initialize("scene");
  return 0;
}

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const aos_fuzz::fs::path dir = aos_fuzz::WorkDir("scene");
  const aos_fuzz::fs::path path = dir / "scene.json";
  aos_fuzz::WriteBytes(path, data, size);
  aos::Scene scene;
  if (!aos_fuzz::Expect("LoadScene", [&] { scene = aos::LoadScene(path.string()); })) return 0;
  aos_fuzz::Expect("ViewLens", [&] { aos::ViewLens(scene); });
  aos_fuzz::Expect("ViewPositions", [&] { aos::ViewPositions(scene); });
  std::string text;
  aos_fuzz::Expect("SceneToJson", [&] { text = aos::SceneToJson(scene); });
  try {
    aos::ParseScene(text, "<round trip>", dir.string());
  } catch (const std::invalid_argument& error) {
    aos_fuzz::Finding("ParseScene(SceneToJson(LoadScene(input)))",
                      std::string("an accepted scene's own JSON is refused: ") + error.what() +
                          "\n" + text);
  } catch (const std::exception& error) {
    aos_fuzz::Finding("ParseScene(SceneToJson(LoadScene(input)))",
                      "unexpected exception " + aos_fuzz::Demangle(typeid(error).name()) +
                          ": " + error.what());
  }
  return 0;
}
