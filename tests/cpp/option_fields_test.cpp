// Field tables (util/option_fields.h) and the JSON form they give every Options struct
// (lightfield/options_json.h): ranges and their text, the range part of Check(), and JSON that
// round-trips every kind of field and names the key of a bad value.
#include <cmath>
#include <limits>
#include <string>

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include "aos/lightfield/formats.h"
#include "aos/lightfield/options_json.h"
#include "aos/plan/flight_plan.h"
#include "aos/render/map.h"
#include "aos/render/focal_surface_json.h"
#include "aos/render/merge.h"
#include "aos/util/option_fields.h"
#include "error_of.h"
#include "temp_folder.h"

namespace aos {
namespace {

using test_util::ErrorOf;
using testing::HasSubstr;
constexpr double kInf = std::numeric_limits<double>::infinity();

TEST(Range, ContainsAndText) {
  const Range angle = Range::ClosedOpen(0.0, 90.0);
  EXPECT_TRUE(angle.Contains(0.0));
  EXPECT_FALSE(angle.Contains(90.0));
  EXPECT_FALSE(angle.Contains(std::nan("")));
  EXPECT_EQ(angle.Text(), "in [0, 90)");
  const Range size = Range::Closed(1, 65536).Or(0);
  EXPECT_TRUE(size.Contains(0.0));
  EXPECT_FALSE(size.Contains(-1.0));
  EXPECT_EQ(size.Text(), "in [1, 65536] or 0");
  EXPECT_TRUE(Range::AtLeast(0.0).Contains(kInf));  // an aperture of every view
  EXPECT_FALSE(Range::FiniteAtLeast(0.0).Contains(kInf));
  EXPECT_EQ(Range::FiniteAtLeast(0.0, true).Text(), "> 0 and finite");
  EXPECT_FALSE(Range::Finite().Contains(-kInf));
  EXPECT_TRUE(Range::Any().IsAny());
  EXPECT_TRUE(Range::Any().Contains(-kInf));
  EXPECT_FALSE(Range::Any().Contains(std::nan("")));
  // Text choices.
  const Range shapes = Range::OneOf("circle|sector|line");
  EXPECT_EQ(shapes.Text(), "one of circle, sector or line");
  EXPECT_EQ(shapes.Choices(), (std::vector<std::string>{"circle", "sector", "line"}));
  EXPECT_TRUE(shapes.ContainsText("sector"));
  EXPECT_FALSE(shapes.ContainsText("Sector"));
  EXPECT_FALSE(shapes.ContainsText(""));
  EXPECT_FALSE(shapes.IsAny());
  EXPECT_TRUE(Range::Any().ContainsText("anything"));
  FlightPlanOptions plan;
  plan.pattern = "spiral";
  EXPECT_THAT(ErrorOf([&] { plan.Check(); }),
              HasSubstr("pattern: must be one of scan, grid or circles, got 'spiral'"));
}

TEST(FieldTable, EveryFieldOnceInDeclarationOrder) {
  EXPECT_EQ(FieldCount<MergeOptions>(), 7u);
  EXPECT_EQ(FieldCount<IntegralOptions>(), 14u);
  std::string names;
  MapOptions::Fields([&](const auto& field) { names += std::string(field.name) + " "; });
  EXPECT_EQ(names,
            "pixel_size width extent focal_surface surface_offset tile_size max_pixels "
            "min_view_count aperture_radius view_indices min_view_angle_deg lens_tolerance_px num_threads ");
}

TEST(FieldTable, CheckRefusesValuesOutsideTheTablesRangeNamingTheField) {
  IntegralOptions options;
  options.min_view_angle_deg = 90.0;
  EXPECT_THAT(ErrorOf([&] { options.Check(1); }),
              HasSubstr("min_view_angle_deg: must be in [0, 90), got 90"));
  options = IntegralOptions{};
  options.width = -3;
  EXPECT_THAT(ErrorOf([&] { options.Check(1); }), HasSubstr("width: must be in [1, 65536] or 0"));
  options = IntegralOptions{};
  options.lens_tolerance_px = std::nan("");
  EXPECT_THAT(ErrorOf([&] { options.Check(1); }), HasSubstr("lens_tolerance_px: must be in [0, 1]"));
  MergeOptions merge;
  merge.robust.agreement = 0.0;
  EXPECT_THAT(ErrorOf([&] { merge.Check(); }), HasSubstr("agreement: must be in (0, 1], got 0"));
  merge = MergeOptions{};
  merge.num_threads = 0;
  EXPECT_THAT(ErrorOf([&] { merge.Check(); }), HasSubstr("num_threads: must be in [1, 1024] or -1"));
}

class OptionsJsonFiles : public testing_util::TempFolderTest {};

// The one focal-surface value in JSON (focal_surface_json.h): a plane as its plane, a number as
// a horizontal plane, a file's surface as its file (read back from it); a surface built in
// memory or moved has no JSON form.
TEST_F(OptionsJsonFiles, AFocalSurfaceTravelsAsItsPlaneOrItsFile) {
  const auto read = [](const std::string& text) {
    return OptionsFromJson<IntegralOptions>(nlohmann::json::parse(text), JsonPath("t"));
  };
  IntegralOptions options;
  options.focal_surface = FocalSurface::FromPlane(Plane{Vec3d(1.0, 2.0, 3.5), Vec3d(0.0, 0.6, 0.8)});
  IntegralOptions back = read(OptionsToJson(options).dump());
  ASSERT_EQ(back.focal_surface.kind(), FocalSurfaceKind::kPlane);
  EXPECT_EQ(back.focal_surface.plane().point, options.focal_surface.plane().point);
  EXPECT_EQ(back.focal_surface.plane().normal, options.focal_surface.plane().normal);
  back = read(R"({"focal_surface": 21.5})");
  EXPECT_EQ(back.focal_surface.plane().point, Vec3d(0.0, 0.0, 21.5));
  EXPECT_EQ(back.focal_surface.plane().normal, Vec3d(0.0, 0.0, 1.0));

  const std::string path = Path("terrain.ply");
  WritePly(path, {Vec3d(0.0, 0.0, 1.0), Vec3d(4.0, 0.0, 1.0), Vec3d(0.0, 4.0, 2.0)}, {{0, 1, 2}});
  options.focal_surface = FocalSurface::Read(path);
  const nlohmann::ordered_json json = OptionsToJson(options);
  EXPECT_EQ(json["focal_surface"]["file"], path);
  back = read(json.dump());
  EXPECT_EQ(back.focal_surface.kind(), FocalSurfaceKind::kMesh);
  EXPECT_TRUE(back.focal_surface.SameAs(options.focal_surface));

  options.focal_surface = FocalSurface::FromMesh(options.focal_surface.mesh());  // in memory
  EXPECT_THAT(ErrorOf([&] { OptionsToJson(options); }),
              HasSubstr("focal_surface: a mesh surface not read from a file as it is has no "
                        "JSON form"));
}

TEST(OptionsJson, RoundTripsEveryKindOfField) {
  AllInFocusOptions options;
  options.merge.method = MergeMethod::kRobust;
  options.merge.robust.agreement = 0.125;
  options.stack.slices = 9;
  options.stack.first_plane = Plane{Vec3d(1.0, 2.0, 3.0), Vec3d(0.0, 0.6, 0.8)};
  options.stack.ground_plane = Plane::AtHeight(-4.0);
  options.stack.render.view_indices = {5, 2, 7};
  options.stack.render.aperture_radius = kInf;
  options.stack.render.cam_from_world = LookAt(Vec3d(1.0, 2.0, 30.0), Vec3d(0.0));
  options.coarse_to_fine = 4;
  const nlohmann::ordered_json json = OptionsToJson(options);
  EXPECT_EQ(json["merge"]["method"], "robust");
  EXPECT_EQ(json["stack"]["render"]["aperture_radius"], "inf");
  EXPECT_EQ(json["stack"]["render"]["focal_surface"].dump(),
            R"({"plane":{"point":[0.0,0.0,0.0],"normal":[0.0,0.0,1.0]}})");
  const AllInFocusOptions back =
      OptionsFromJson<AllInFocusOptions>(nlohmann::json::parse(json.dump()), JsonPath("t"));
  EXPECT_EQ(OptionsToJson(back).dump(), json.dump());
  EXPECT_EQ(back.stack.render.view_indices, options.stack.render.view_indices);
  EXPECT_TRUE(back.stack.ground_plane.has_value());
  EXPECT_EQ(back.stack.render.cam_from_world.translation,
            options.stack.render.cam_from_world.translation);

  FlightPlanOptions plan;
  plan.center = {10.0, 20.0};
  plan.vertices = {{0.0, 0.0}, {5.0, 0.0}, {0.0, 5.0}};
  const FlightPlanOptions plan_back =
      OptionsFromJson<FlightPlanOptions>(nlohmann::json::parse(OptionsToJson(plan).dump()),
                                         JsonPath("t"));
  EXPECT_EQ(plan_back.vertices, plan.vertices);
  EXPECT_EQ(plan_back.center, plan.center);
}

TEST(OptionsJson, BadValuesNameTheFileAndTheKey) {
  auto error = [](const std::string& text) {
    return ErrorOf([&] { OptionsFromJson<MapOptions>(nlohmann::json::parse(text), JsonPath("spec")); });
  };
  EXPECT_THAT(error(R"({"tile_sise": 5})"), HasSubstr("spec: /tile_sise: unknown key (known: "));
  EXPECT_THAT(error(R"({"tile_size": 5.5})"), HasSubstr("spec: /tile_size: expected a whole number"));
  EXPECT_THAT(error(R"({"aperture_radius": "huge"})"), HasSubstr("/aperture_radius: expected a number"));
  EXPECT_THAT(error(R"({"extent": [0, 1, "x", 3]})"), HasSubstr("/extent/2: expected a number"));
  EXPECT_THAT(error(R"({"focal_surface": "dem.tif"})"),
              HasSubstr("/focal_surface: expected a number (the height of a horizontal plane), "
                        "{\"plane\": {...}} or {\"file\": PATH}"));
  EXPECT_THAT(error(R"({"focal_surface": {"file": "/no/such/dem.tif"}})"),
              HasSubstr("spec: /focal_surface/file: "));
  EXPECT_THAT(error(R"({"focal_surface": {"plane": {"point": [0, 0, 0], "normal": [0, 0, 0]}}})"),
              HasSubstr("spec: /focal_surface/plane/normal: must not be zero"));
  EXPECT_THAT(error(R"({"focal_surface": {"plane": {"point": [0, 0, 1e20], "normal": [0, 0, 1]}}})"),
              HasSubstr("spec: /focal_surface: focal_surface: plane: point z is 1e+20 m"));
  EXPECT_THAT(ErrorOf([] {
                OptionsFromJson<MergeOptions>(nlohmann::json::parse(R"({"method": "best"})"),
                                              JsonPath("spec"));
              }),
              HasSubstr("spec: /method: unknown value 'best' (one of sobel, improved, robust)"));
  MapOptions nan;
  nan.surface_offset = std::nan("");
  EXPECT_THAT(ErrorOf([&] { OptionsToJson(nan); }), HasSubstr("surface_offset: a NaN"));
}

}  // namespace
}  // namespace aos

namespace aos {
namespace {

TEST(LensModelTraits, OneRowPerModelReadByNamesParametersAndColmap) {
  for (const LensModelTraits& traits : kLensModels) {
    EXPECT_EQ(ParseLensModel(traits.name, "model"), traits.model);
    EXPECT_STREQ(LensModelName(traits.model), traits.name);
    EXPECT_STREQ(EnumName(traits.model), traits.name);
    for (int i = 0; i < traits.distortion_count; ++i) {
      EXPECT_EQ(DistortionIndex(traits.model, traits.distortion_names[static_cast<size_t>(i)]), i);
    }
  }
  EXPECT_EQ(DistortionIndex(LensModel::kFisheye, "p1"), -1);
  EXPECT_EQ(DistortionIndex(LensModel::kPinhole, "k1"), -1);
  EXPECT_EQ(DistortionIndex(LensModel::kRadTan, "k3"), 4);
  EXPECT_THAT(ErrorOf([] { ParseLensModel("kannala", "model"); }),
              HasSubstr("model: unknown lens model 'kannala' (pinhole, radtan, fisheye, omnidir)"));
  EXPECT_TRUE(TraitsOf(LensModel::kRadTan).perspective);
  EXPECT_FALSE(TraitsOf(LensModel::kOmnidir).perspective);
  EXPECT_STREQ(TraitsOf(LensModel::kOmnidir).colmap_model, "");
}

}  // namespace
}  // namespace aos
