// libFuzzer harness: the mesh readers (aos::ReadMesh and aos::ReadPoints, geometry/mesh.h), built
// twice: AOS_FUZZ_MESH_EXTENSION ".obj" and ".ply" (the file's name; ReadMesh picks PLY by the
// leading "ply" whatever the name, so each build reaches both parsers, starting from its seeds).
//
// Beyond the error contract, an accepted mesh must pass its own Mesh::Check (finite vertices,
// indices in range, at least one triangle) and keep no degenerate triangle: ReadMesh documents
// both, and the renderer relies on them.
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <string>
#include <string_view>

#include "aos/geometry/mesh.h"
#include "fuzz_util.h"

#ifndef AOS_FUZZ_MESH_EXTENSION
#error "define AOS_FUZZ_MESH_EXTENSION as \".obj\" or \".ply\""
#endif

namespace {
constexpr const char* kHarness =
    std::string_view(AOS_FUZZ_MESH_EXTENSION) == ".obj" ? "mesh_obj" : "mesh_ply";
}

extern "C" int LLVMFuzzerInitialize(int*, char***) {
  aos_fuzz::Initialize(kHarness);
  return 0;
}

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const aos_fuzz::fs::path path =
      aos_fuzz::WorkDir(kHarness) / (std::string("mesh") + AOS_FUZZ_MESH_EXTENSION);
  aos_fuzz::WriteBytes(path, data, size);
  aos::Mesh mesh;
  if (aos_fuzz::Expect("ReadMesh", [&] { mesh = aos::ReadMesh(path.string()); })) {
    try {
      mesh.Check("<accepted mesh>");
    } catch (const std::invalid_argument& error) {
      aos_fuzz::Finding("ReadMesh", std::string("an accepted mesh fails Mesh::Check: ") +
                                        error.what());
    }
    for (const auto& triangle : mesh.triangles) {
      if (triangle[0] == triangle[1] || triangle[1] == triangle[2] || triangle[0] == triangle[2]) {
        aos_fuzz::Finding("ReadMesh", "an accepted mesh keeps a triangle with a repeated vertex");
      }
    }
  }
  aos_fuzz::Expect("ReadPoints", [&] {
    for (const aos::Vec3d& point : aos::ReadPoints(path.string())) {
      if (!std::isfinite(point.x) || !std::isfinite(point.y) || !std::isfinite(point.z)) {
        aos_fuzz::Finding("ReadPoints", "an accepted point is not finite");
      }
    }
  });
  return 0;
}
