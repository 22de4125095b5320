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
#include "aos/render/merge.h"
#include "aos/util/option_fields.h"
#include "error_of.h"

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
}

TEST(FieldTable, EveryFieldOnceInDeclarationOrder) {
  EXPECT_EQ(FieldCount<MergeOptions>(), 7u);
  EXPECT_EQ(FieldCount<IntegralOptions>(), 14u);
  std::string names;
  MapOptions::Fields([&](const auto& field) { names += std::string(field.name) + " "; });
  EXPECT_EQ(names,
            "pixel_size width extent focal_height focal_surface surface_offset tile_size max_pixels "
            "aperture_radius view_indices min_view_angle_deg lens_tolerance_px num_threads ");
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
  EXPECT_TRUE(json["stack"]["render"].contains("focal_plane"));
  EXPECT_FALSE(json["stack"]["render"].contains("focal_surface"));  // not carried
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
  EXPECT_THAT(error(R"({"focal_surface": "dem.tif"})"), HasSubstr("/focal_surface: not carried"));
  EXPECT_THAT(ErrorOf([] {
                OptionsFromJson<MergeOptions>(nlohmann::json::parse(R"({"method": "best"})"),
                                              JsonPath("spec"));
              }),
              HasSubstr("spec: /method: unknown value 'best' (one of sobel, improved, robust)"));
  MapOptions nan;
  nan.focal_height = std::nan("");
  EXPECT_THAT(ErrorOf([&] { OptionsToJson(nan); }), HasSubstr("NaN"));
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
