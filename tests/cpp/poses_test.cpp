// The COLMAP pipeline's parts that need no COLMAP: the process runner, positions files,
// geo-referencing of a light field, and the pipeline's errors (with a stand-in COLMAP script).
// The pipeline itself against COLMAP is tested from Python (tests/python/test_poses.py).
#include "aos/sfm/colmap_pipeline.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <random>

#include <sqlite3.h>
#include <sys/wait.h>

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <OpenImageIO/imageio.h>

#include "aos/geometry/geodesy.h"
#include "aos/image/image_io.h"
#include "aos/lightfield/formats.h"
#include "aos/util/error.h"
#include "aos/util/math.h"
#include "aos/util/file_util.h"
#include "aos/util/process.h"
#include "error_of.h"
#include "gps_frame.h"
#include "temp_folder.h"

namespace aos {
namespace {

using ::testing::ElementsAre;
using ::testing::HasSubstr;
using test_util::ErrorOf;

TEST(Process, StreamsLinesAndReturnsTheExitStatus) {
  std::vector<std::string> lines;
  const int status = RunProcess({"sh", "-c", "echo one; echo two 1>&2; printf 'a\\rb'; exit 3"},
                                [&](const std::string& line) { lines.push_back(line); });
  EXPECT_EQ(status, 3);
  EXPECT_THAT(lines, ElementsAre("one", "two", "a", "b"));
  EXPECT_EQ(RunProcess({"sh", "-c", "kill -9 $$"}, nullptr), 128 + 9);
}

TEST(Process, MissingProgramsAreNamed) {
  EXPECT_FALSE(ProgramExists("no-such-program-aos"));
  EXPECT_TRUE(ProgramExists("sh"));
  EXPECT_THAT(ErrorOf([] { RunProcess({"no-such-program-aos", "x"}, nullptr); }),
              HasSubstr("no-such-program-aos: not found"));
  EXPECT_THAT(ErrorOf([] { RunProcess({"/nonexistent/colmap"}, nullptr); }),
              HasSubstr("/nonexistent/colmap: not found"));
}

TEST(Process, LargeOutputNeverDeadlocks) {
  int64_t lines = 0;
  EXPECT_EQ(RunProcess({"seq", "1", "300000"}, [&](const std::string&) { ++lines; }), 0);
  EXPECT_EQ(lines, 300000);
}

TEST(Process, AThrowingCallbackStopsAndReapsTheChild) {
  const auto start = std::chrono::steady_clock::now();
  EXPECT_THROW(RunProcess({"sh", "-c", "echo first; sleep 30"},
                          [](const std::string&) { throw std::runtime_error("stop"); }),
               std::runtime_error);
  EXPECT_LT(std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count(), 10.0);
  EXPECT_EQ(::waitpid(-1, nullptr, WNOHANG), -1);  // no child of ours is left (ECHILD)
}

TEST(Process, AChildIgnoringSigtermIsKilled) {
  // The child ignores SIGTERM: after the 2 s grace period it gets SIGKILL.
  int polls = 0;
  const auto start = std::chrono::steady_clock::now();
  EXPECT_THROW(RunProcess({"sh", "-c", "trap '' TERM; echo ready; while :; do sleep 1; done"},
                          nullptr, [&] { return ++polls > 3; }),
               Cancelled);
  const double seconds =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  EXPECT_GT(seconds, 1.9);
  EXPECT_LT(seconds, 10.0);
  EXPECT_EQ(::waitpid(-1, nullptr, WNOHANG), -1);
}

TEST(Process, CancellingStopsTheChildPromptly) {
  const auto start = std::chrono::steady_clock::now();
  int polls = 0;
  EXPECT_THROW(RunProcess({"sleep", "30"}, nullptr, [&] { return ++polls > 2; }), Cancelled);
  // SIGTERM ends sleep at once; the bound only guards against waiting for the 30 s.
  EXPECT_LT(std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count(), 10.0);
}

TEST(Geodesy, UtmMatchesReferenceCoordinates) {
  // The Eiffel Tower, 48.8582 N 2.2945 E: 31N 448251.795 E 5411932.678 N (GeographicLib, as
  // pygeodesy's tests give it to the millimetre).
  const UtmCoordinate paris = UtmFromWgs84(48.8582, 2.2945);
  EXPECT_EQ(paris.zone, 31);
  EXPECT_TRUE(paris.north);
  EXPECT_NEAR(paris.easting, 448251.795, 1e-3);
  EXPECT_NEAR(paris.northing, 5411932.678, 1e-3);
  // On the central meridian the easting is exactly the false easting; the equator is northing 0.
  EXPECT_NEAR(UtmFromWgs84(0.0, 3.0).easting, 500000.0, 1e-9);
  EXPECT_NEAR(UtmFromWgs84(0.0, 3.0).northing, 0.0, 1e-9);
  // The projection is symmetric about the equator: south = 10,000 km - north.
  const UtmCoordinate south = UtmFromWgs84(-48.8582, 2.2945);
  EXPECT_FALSE(south.north);
  EXPECT_NEAR(south.easting, paris.easting, 1e-6);
  EXPECT_NEAR(south.northing, 10000000.0 - paris.northing, 1e-6);
  // A forced zone keeps neighbours in one frame (the next zone's meridian is 6 degrees east).
  const UtmCoordinate forced = UtmFromWgs84(48.8582, 2.2945, 32);
  EXPECT_EQ(forced.zone, 32);
  EXPECT_LT(forced.easting, 100000.0);
  // Longitudes wrap; zone 60 ends at 180 degrees.
  EXPECT_EQ(UtmFromWgs84(10.0, 179.9).zone, 60);
  EXPECT_EQ(UtmFromWgs84(10.0, -179.9).zone, 1);
  EXPECT_THAT(ErrorOf([] { UtmFromWgs84(85.0, 0.0, 0, "frame.jpg: GPS"); }),
              HasSubstr("frame.jpg: GPS: latitude 85 is outside UTM's range"));
  EXPECT_THAT(ErrorOf([] { UtmFromWgs84(std::nan(""), 0.0); }), HasSubstr("must be finite"));
}

TEST(Geodesy, TransformPointsMatchesReferenceFiguresAndRelatesDatums) {
  // WGS84 longitude/latitude (visualisation order: longitude first) to UTM 31N: the Eiffel Tower's
  // reference figures to the millimetre, through the general transform.
  const std::vector<Vec3d> paris =
      TransformPoints({Vec3d(2.2945, 48.8582, 35.0)}, "EPSG:4326", "EPSG:32631", "test");
  ASSERT_EQ(paris.size(), 1u);
  EXPECT_NEAR(paris[0].x, 448251.795, 1e-3);
  EXPECT_NEAR(paris[0].y, 5411932.678, 1e-3);
  EXPECT_NEAR(paris[0].z, 35.0, 1e-9);  // 2-D CRSs: heights pass through
  // And back, to 1e-9 degrees (0.1 mm).
  const std::vector<Vec3d> back = TransformPoints(paris, "EPSG:32631", "EPSG:4326", "test");
  EXPECT_NEAR(back[0].x, 2.2945, 1e-9);
  EXPECT_NEAR(back[0].y, 48.8582, 1e-9);
  // ETRS89 / UTM 33N and WGS84 / UTM 33N: the same projection on datums that differ by well
  // under a metre (PROJ relates them by a null or ballpark transformation here): < 1 m apart, and
  // the round trip closes to a micrometre.
  const std::vector<Vec3d> etrs = {Vec3d(500000.0, 5300000.0, 400.0), Vec3d(432101.5, 5350123.25, 0.0)};
  const std::vector<Vec3d> wgs = TransformPoints(etrs, "EPSG:25833", "EPSG:32633", "dem.tif");
  const std::vector<Vec3d> again = TransformPoints(wgs, "EPSG:32633", "EPSG:25833", "dem.tif");
  for (size_t i = 0; i < etrs.size(); ++i) {
    EXPECT_LT(std::hypot(wgs[i].x - etrs[i].x, wgs[i].y - etrs[i].y), 1.0);
    EXPECT_NEAR(again[i].x, etrs[i].x, 1e-6);
    EXPECT_NEAR(again[i].y, etrs[i].y, 1e-6);
  }
  // A CRS PROJ does not know, or cannot relate, is an error naming `where`.
  EXPECT_THAT(ErrorOf([] { TransformPoints({Vec3d(0.0)}, "EPSG:999999", "EPSG:32633", "dem.tif"); }),
              HasSubstr("dem.tif: CRS 'EPSG:999999' is not known to PROJ"));
  EXPECT_THAT(ErrorOf([] { TransformPoints({Vec3d(0.0)}, "EPSG:32633", "no such crs", "dem.tif"); }),
              HasSubstr("dem.tif: CRS 'no such crs' is not known to PROJ"));
  // A Mars CRS and an Earth one have no transformation between them.
  EXPECT_THAT(ErrorOf([] {
                TransformPoints({Vec3d(0.0)}, "IAU_2015:49900", "EPSG:4326", "mars.tif");
              }),
              HasSubstr("mars.tif"));
  EXPECT_THAT(ErrorOf([] {
                TransformPoints({Vec3d(std::nan(""), 0.0, 0.0)}, "EPSG:4326", "EPSG:32633", "f");
              }),
              HasSubstr("f: point 0 is not finite"));
}

TEST(Geodesy, LightFieldCrsMustBeAMetricEpsgCode) {
  EXPECT_NO_THROW(CheckLightFieldCrs("", "lf.json: crs"));
  EXPECT_NO_THROW(CheckLightFieldCrs("EPSG:32633", "lf.json: crs"));
  EXPECT_NO_THROW(CheckLightFieldCrs("EPSG:25833", "lf.json: crs"));
  EXPECT_THAT(ErrorOf([] { CheckLightFieldCrs("EPSG:4326", "lf.json: crs"); }),
              HasSubstr("lf.json: crs: EPSG:4326 (WGS 84) is geographic (degrees)"));
  EXPECT_THAT(ErrorOf([] { CheckLightFieldCrs("EPSG:999999", "lf.json: crs"); }),
              HasSubstr("lf.json: crs: EPSG:999999 is not known to PROJ"));
  EXPECT_THAT(ErrorOf([] { CheckLightFieldCrs("UTM 33N", "lf.json: crs"); }),
              HasSubstr("lf.json: crs: \"UTM 33N\" is not an EPSG code"));
  EXPECT_THAT(ErrorOf([] { CheckLightFieldCrs("EPSG:2263", "lf.json: crs"); }),  // US feet
              HasSubstr("has axes in"));
  EXPECT_THAT(ErrorOf([] { CheckLightFieldCrs("EPSG:4978", "lf.json: crs"); }),  // geocentric
              HasSubstr("is not a projected CRS"));
  // EPSG codes: a CRS's own, or identified by PROJ from its name.
  EXPECT_EQ(EpsgOfCrs("EPSG:25833", "f"), "EPSG:25833");
  EXPECT_EQ(UtmEpsg(33, true), "EPSG:32633");
  EXPECT_EQ(UtmEpsg(19, false), "EPSG:32719");
  EXPECT_EQ(MetricFromCrs({Vec3d(14.3, 48.3, 0.0)}, "EPSG:4326", "f").crs, "EPSG:32633");
  EXPECT_EQ(MetricFromCrs({Vec3d(500000.0, 5300000.0, 0.0)}, "EPSG:25833", "f").crs, "EPSG:25833");
}

TEST(Geodesy, GridBearingOfNorthIsTheMeridianConvergence) {
  // On a zone's central meridian grid north is true north.
  EXPECT_NEAR(GridBearingOfNorth(48.0, 15.0, "EPSG:32633", "t"), 0.0, 1e-9);
  // East of it (northern hemisphere) true north lies west of grid north by the convergence
  // gamma = atan(tan(dlon) sin(lat)) (spherical; the ellipsoid changes it by < 0.001 degrees
  // here).
  const double lat = 48.0 * kPi / 180.0, dlon = 2.9 * kPi / 180.0;
  const double gamma = std::atan(std::tan(dlon) * std::sin(lat));
  EXPECT_NEAR(GridBearingOfNorth(48.0, 17.9, "EPSG:32633", "t"), -gamma, 0.001 * kPi / 180.0);
  EXPECT_NEAR(GridBearingOfNorth(48.0, 12.1, "EPSG:32633", "t"), gamma, 0.001 * kPi / 180.0);
}

class ExifFrames : public testing_util::TempFolderTest {
 protected:
  // A small JPEG with GPS tags as a drone writes them (degrees, minutes, seconds + refs).
  void WriteTagged(const std::string& name, double lat, double lon, double altitude,
                   bool with_altitude = true) {
    const std::optional<double> tagged_altitude =
        with_altitude ? std::optional<double>(altitude) : std::nullopt;
    ASSERT_TRUE(testing_util::WriteGpsTaggedFrame(Path(name), 16, 12, lat, lon, tagged_altitude));
  }
};

TEST_F(ExifFrames, GpsTagsBecomeUtmPositions) {
  WriteTagged("a.jpg", 48.8582, 2.2945, 135.5);
  WriteTagged("b.jpg", -33.5, -70.25, -12.0);  // south, west, below sea level
  WriteTagged("c.jpg", 48.8583, 2.2946, 0.0, /*with_altitude=*/false);
  Image plain(8, 8, 1, PixelType::kU8);
  WriteImage(Path("d.png"), plain);
  const std::optional<GpsTag> a = ReadGpsTag(Path("a.jpg"));
  ASSERT_TRUE(a.has_value());
  // EXIF stores seconds as rationals (float here): within 1e-6 degrees (0.1 m).
  EXPECT_NEAR(a->latitude_deg, 48.8582, 1e-6);
  EXPECT_NEAR(a->longitude_deg, 2.2945, 1e-6);
  EXPECT_NEAR(a->altitude_m, 135.5, 1e-4);
  const std::optional<GpsTag> b = ReadGpsTag(Path("b.jpg"));
  ASSERT_TRUE(b.has_value());
  EXPECT_NEAR(b->latitude_deg, -33.5, 1e-6);
  EXPECT_NEAR(b->longitude_deg, -70.25, 1e-6);
  EXPECT_NEAR(b->altitude_m, -12.0, 1e-4);
  EXPECT_TRUE(std::isnan(ReadGpsTag(Path("c.jpg"))->altitude_m));
  EXPECT_FALSE(ReadGpsTag(Path("d.png")).has_value());
  // Positions: UTM in the first tagged frame's zone; frames without a full fix are skipped.
  std::vector<std::string> skipped;
  std::string zone;
  const std::vector<NamedPosition> positions =
      PositionsFromExif(dir_.string(), {"a.jpg", "c.jpg", "d.png"}, &skipped, &zone);
  ASSERT_EQ(positions.size(), 1u);
  EXPECT_EQ(zone, "UTM 31N (WGS84)");
  EXPECT_THAT(skipped, ElementsAre("c.jpg", "d.png"));
  EXPECT_NEAR(positions[0].position.x, 448251.795, 0.1);
  EXPECT_NEAR(positions[0].position.y, 5411932.678, 0.1);
  EXPECT_NEAR(positions[0].position.z, 135.5, 1e-4);
}

class PoseSourceFiles : public testing_util::TempFolderTest {};

TEST_F(PoseSourceFiles, RoundTripAndWrongTypesAreNamed) {
  LightField light_field;
  Image image(8, 6, 1, PixelType::kU8);
  light_field.views.push_back(MakeView("a", PinholeCamera::FromFov(8, 6, 60.0), Rigid3d(), image));
  PoseSource source;
  source.method = "colmap";
  source.mean_reprojection_error_px = 0.4;
  source.median_depth = 20.0;
  source.pose_error = 0.02;
  source.georeferenced = true;
  source.georeference_rms_m = 0.01;
  source.world_frame = "the frame of gps.csv";  // metres in a frame without an EPSG code
  source.unregistered = {"x.png"};
  light_field.pose_source = source;
  WriteLightField(Path("lf.json"), light_field);
  const LightField back = LoadLightField(Path("lf.json")).light_field;
  ASSERT_TRUE(back.pose_source.has_value());
  EXPECT_EQ(back.pose_source->world_frame, "the frame of gps.csv");
  EXPECT_EQ(back.crs, "");
  EXPECT_EQ(back.pose_source->unregistered, std::vector<std::string>{"x.png"});
  EXPECT_EQ(back.pose_source->pose_error, 0.02);
  EXPECT_TRUE(back.pose_source->georeferenced);
  const std::string text = ReadTextFile(Path("lf.json"));
  const auto corrupt = [&](const std::string& from, const std::string& to) {
    std::string bad = text;
    const size_t at = bad.find(from);
    EXPECT_NE(at, std::string::npos) << from;
    bad.replace(at, from.size(), to);
    WriteTextFileAtomic(Path("bad.json"), bad);
    return ErrorOf([&] { LoadLightField(Path("bad.json")); });
  };
  EXPECT_THAT(corrupt("\"georeferenced\": true", "\"georeferenced\": 1"),
              HasSubstr("bad.json: /pose_source/georeferenced: expected true or false"));
  EXPECT_THAT(corrupt("\"pose_error\": 0.02", "\"pose_error\": -1"),
              HasSubstr("bad.json: /pose_source/pose_error: expected a finite number >= 0"));
  EXPECT_THAT(corrupt("\"method\": \"colmap\"", "\"method\": 3"),
              HasSubstr("bad.json: /pose_source/method: expected a string"));
  // A misspelled key of the pose record is refused with its key path (json_codec.h).
  EXPECT_THAT(corrupt("\"world_frame\"", "\"world_frmae\""),
              HasSubstr("bad.json: /pose_source/world_frmae: unknown key"));
  EXPECT_THAT(corrupt("\"unregistered\": [", "\"unregistered\": [7, "),
              HasSubstr("bad.json: /pose_source/unregistered/0: expected a frame name"));
}

class PositionsFiles : public testing_util::TempFolderTest {
 protected:
  std::string Write(const std::string& name, const std::string& text) {
    std::ofstream(Path(name)) << text;
    return Path(name);
  }
};

TEST_F(PositionsFiles, ReadsNamesAndMetricCoordinates) {
  const std::string path = Write("gps.csv",
                                 "name, x, y, z\r\n# a comment\n\na.png, 500000.25, 5300000.5, "
                                 "420\nb.png,500010,5300001,421.5\n");
  const PositionsFile file = ReadPositionsFile(path);
  const std::vector<NamedPosition>& positions = file.positions;
  EXPECT_EQ(file.world_frame, "the frame of " + path);
  ASSERT_EQ(positions.size(), 2u);
  EXPECT_EQ(positions[0].name, "a.png");
  EXPECT_EQ(positions[0].position, Vec3d(500000.25, 5300000.5, 420.0));
  EXPECT_EQ(positions[1].position, Vec3d(500010.0, 5300001.0, 421.5));
}

TEST_F(PositionsFiles, ColumnsAreReadByNameAndDegreesProjectedWithProj) {
  // A name,lat,lon,alt file was read as metres (origin "48.300 14.300"): columns go by name now,
  // and degrees are projected to UTM (zone 33 for 14.3 E) through PROJ.
  const std::string path = Write("gps.csv",
                                 "name,lat,lon,alt\na.png,48.3,14.3,350\nb.png,48.3001,14.3,351\n");
  const PositionsFile file = ReadPositionsFile(path);
  EXPECT_EQ(file.world_frame, "UTM 33N (WGS 84)");
  const UtmCoordinate a = UtmFromWgs84(48.3, 14.3);
  EXPECT_NEAR(file.positions[0].position.x, a.easting, 1e-6);
  EXPECT_NEAR(file.positions[0].position.y, a.northing, 1e-6);
  EXPECT_EQ(file.positions[0].position.z, 350.0);
  // 0.0001 degrees of latitude is about 11.1 m.
  EXPECT_NEAR(file.positions[1].position.y - file.positions[0].position.y, 11.12, 0.01);
  // Columns in another order, other names, and an explicit projected CRS (ETRS89 / UTM 33N).
  const PositionsFile utm = ReadPositionsFile(
      Write("utm.csv", "Easting,Northing,Altitude,Image\n500000,5300000,400,a.png\n"), "EPSG:25833");
  EXPECT_EQ(utm.positions[0].name, "a.png");
  EXPECT_EQ(utm.positions[0].position, Vec3d(500000.0, 5300000.0, 400.0));
  EXPECT_THAT(utm.world_frame, HasSubstr("UTM zone 33N"));
  // x, y in degrees with the CRS stated.
  const PositionsFile stated =
      ReadPositionsFile(Write("xy.csv", "name,x,y,z\na.png,14.3,48.3,350\n"), "EPSG:4326");
  EXPECT_NEAR(stated.positions[0].position.x, a.easting, 1e-6);
  // Degrees given as metres are refused, as are unknown columns and CRSs.
  EXPECT_THAT(ErrorOf([&] {
                ReadPositionsFile(Write("deg.csv", "a.png,48.3,14.3,350\nb.png,48.3001,14.3,351\n"));
              }),
              HasSubstr("deg.csv: line 1: x, y look like degrees"));
  EXPECT_THAT(ErrorOf([&] { ReadPositionsFile(Write("f.csv", "name,lat,lon,speed\na,1,2,3\n")); }),
              HasSubstr("f.csv: line 1: column 4 \"speed\" is not one of"));
  EXPECT_THAT(ErrorOf([&] { ReadPositionsFile(path, "EPSG:999999"); }),
              HasSubstr("'EPSG:999999' is not known to PROJ"));
  EXPECT_THAT(ErrorOf([&] { ReadPositionsFile(Write("feet.csv", "a.png,1,2,3\n"), "EPSG:2263"); }),
              HasSubstr("aos needs metres"));
  // The EPSG code of the metric frame: the UTM zone degrees were projected to, or the stated
  // projected CRS; none for metres in an unstated frame.
  EXPECT_EQ(file.crs, "EPSG:32633");
  EXPECT_EQ(utm.crs, "EPSG:25833");
  EXPECT_EQ(stated.crs, "EPSG:32633");
  EXPECT_EQ(ReadPositionsFile(Write("m.csv", "a.png,500000,5300000,1\n")).crs, "");
}

TEST_F(PositionsFiles, PositionsCrsContradictingTheValuesIsNamed) {
  // A geographic CRS with values out of degree range (UTM metres given as EPSG:4326): the file,
  // line and field.
  EXPECT_THAT(ErrorOf([&] {
                ReadPositionsFile(Write("utm.csv", "name,x,y,z\na.png,14.3,48.3,1\n"
                                                   "b.png,500000,5300000,1\n"),
                                  "EPSG:4326");
              }),
              HasSubstr("utm.csv: line 3: x: 500000 is not a longitude in [-180, 180] degrees, "
                        "as positions_crs EPSG:4326 is geographic"));
  EXPECT_THAT(ErrorOf([&] {
                ReadPositionsFile(Write("lat.csv", "name,lat,lon,alt\na.png,95,14.3,1\n"));
              }),
              HasSubstr("lat.csv: line 2: lat: 95 is not a latitude in [-90, 90]"));
  // Degrees given where a projected CRS expects metres.
  EXPECT_THAT(ErrorOf([&] {
                ReadPositionsFile(Write("deg.csv", "a.png,14.3,48.3,350\nb.png,14.3001,48.3,351\n"),
                                  "EPSG:32633");
              }),
              HasSubstr("deg.csv: line 1: x, y look like degrees (all 2 positions within 0.1 of "
                        "(14.3, 48.3)) but positions_crs EPSG:32633 is in metres"));
  // lat/lon columns (degrees) with a projected CRS contradict each other.
  EXPECT_THAT(ErrorOf([&] {
                ReadPositionsFile(Write("mix.csv", "name,lat,lon,alt\na.png,48.3,14.3,1\n"),
                                  "EPSG:32633");
              }),
              HasSubstr("mix.csv: the header names lat, lon columns (degrees) but positions_crs "
                        "EPSG:32633 is not geographic"));
}

TEST_F(PositionsFiles, MalformedLinesAreNamed) {
  EXPECT_THAT(ErrorOf([&] { ReadPositionsFile(Write("a.csv", "a.png,1,2\n")); }),
              HasSubstr("a.csv: line 1: expected 4 comma-separated fields"));
  EXPECT_THAT(ErrorOf([&] { ReadPositionsFile(Write("b.csv", "a.png,1,2,3\nb.png,1,x,3\n")); }),
              HasSubstr("b.csv: line 2: y: \"x\" is not a number"));
  EXPECT_THAT(ErrorOf([&] { ReadPositionsFile(Write("c.csv", "a.png,1,2,3\na.png,1,2,3\n")); }),
              HasSubstr("c.csv: line 2: name: \"a.png\" is repeated"));
  EXPECT_THAT(ErrorOf([&] { ReadPositionsFile(Write("d.csv", "a.png,1,inf,3\n")); }),
              HasSubstr("d.csv: line 1: y: inf is not finite"));
  EXPECT_THAT(ErrorOf([&] { ReadPositionsFile(Write("e.csv", "# nothing\n")); }),
              HasSubstr("e.csv: no positions"));
  EXPECT_THAT(ErrorOf([&] { ReadPositionsFile(Path("missing.csv")); }),
              HasSubstr("missing.csv: positions file not found"));
}

TEST_F(PositionsFiles, AByteOrderMarkAndQuotedFieldsAreRead) {
  // Issue 31: a spreadsheet's UTF-8 byte-order mark made the header's first column unknown, and
  // a quoted name with a comma split into two fields. The tokenizer is util/csv.h, shared with
  // the telemetry reader.
  const PositionsFile file = ReadPositionsFile(Write("bom.csv",
                                                     "\xEF\xBB\xBFname,x,y,z\r\n"
                                                     "\"a,1.png\",500000,5300000,420\r\n"
                                                     "\"b \"\"2\"\".png\",\"500010\",5300001,421\r\n"));
  ASSERT_EQ(file.positions.size(), 2u);
  EXPECT_EQ(file.positions[0].name, "a,1.png");
  EXPECT_EQ(file.positions[1].name, "b \"2\".png");
  EXPECT_EQ(file.positions[1].position, Vec3d(500010.0, 5300001.0, 421.0));
  EXPECT_THAT(ErrorOf([&] { ReadPositionsFile(Write("q.csv", "a.png,1,\"2,3\n")); }),
              HasSubstr("q.csv: line 1: field 3: its opening quote is never closed"));
}

// Views whose poses are the true ones seen through an arbitrary similarity (COLMAP's frame).
struct ModelFrameLightField {
  LightField light_field;
  std::vector<std::string> names;
  std::vector<NamedPosition> positions;  // true centres, UTM-sized
  std::vector<Rigid3d> true_local;       // true poses about the positions' mean
};

ModelFrameLightField MakeModelFrameLightField(double baseline_m) {
  ModelFrameLightField m;
  const Vec3d utm(512345.678, 5301234.567, 431.0);
  Sim3d model_from_true;
  model_from_true.scale = 0.037;
  model_from_true.rotation = LookAt(Vec3d(0.0), Vec3d(0.3, -0.2, 1.0), Vec3d(0.1, 1.0, 0.2)).rotation;
  model_from_true.translation = Vec3d(3.0, -1.0, 2.5);
  std::vector<Vec3d> centres;
  for (int j = 0; j < 3; ++j) {
    for (int i = 0; i < 3; ++i) {
      centres.push_back(utm + Vec3d(baseline_m * i, baseline_m * j + 0.1 * baseline_m * i,
                                    0.05 * baseline_m * (i + j) * (i == 1 ? 1 : 0)));
    }
  }
  Vec3d mean(0.0);
  for (const Vec3d& c : centres) mean += c;
  mean /= static_cast<double>(centres.size());
  for (size_t k = 0; k < centres.size(); ++k) {
    const std::string name = "f" + std::to_string(k) + ".png";
    m.names.push_back("flight/" + name);
    m.positions.push_back({name, centres[k]});
    const Rigid3d local = NadirCamFromWorld(centres[k] - mean);
    m.true_local.push_back(local);
    // Model frame: x_model = s R (x_true - mean) + t, so cam_from_model = cam_from_true o inverse.
    View view;
    view.cam_from_world = TransformCamFromWorld(model_from_true, local);
    m.light_field.views.push_back(view);
  }
  return m;
}

TEST(Georeference, RecoversTheTrueFrameAtUtmCoordinates) {
  ModelFrameLightField m = MakeModelFrameLightField(8.0);
  const GeoreferenceResult result = Georeference(&m.light_field, m.names, m.positions, "gps.csv");
  EXPECT_EQ(result.frames, 9);
  EXPECT_LT(result.rms_m, 1e-9);
  Vec3d mean(0.0);
  for (const NamedPosition& p : m.positions) mean += p.position;
  mean /= 9.0;
  EXPECT_EQ(m.light_field.origin, mean);
  for (size_t k = 0; k < m.true_local.size(); ++k) {
    const Rigid3d& got = m.light_field.views[k].cam_from_world;
    // Centres to 1e-9 m: the poses are about the origin, so UTM magnitudes never enter them.
    EXPECT_LT(glm::length(got.Center() - m.true_local[k].Center()), 1e-9);
    for (int c = 0; c < 3; ++c) {
      EXPECT_LT(glm::length(got.rotation[c] - m.true_local[k].rotation[c]), 1e-9);
    }
  }
}

// The angle between the optical axes (camera z in world) of two poses, degrees.
double AxisAngleDeg(const Rigid3d& a, const Rigid3d& b) {
  const double c = glm::dot(Row(a.rotation, 2), Row(b.rotation, 2));
  return std::acos(std::clamp(c, -1.0, 1.0)) * 180.0 / M_PI;
}

TEST(Georeference, AStraightFlightTakesItsRollFromTheViewingDirection) {
  // Eight nadir cameras on a 70 m straight line, GPS noise of up to 0.25 m across it: a plain
  // similarity fit let the noise pick the roll about the line (it tilted the cameras by tens of
  // degrees with a sub-metre residual). The viewing direction fixes it: the cameras come out
  // within a degree of nadir, and a warning says how the roll was found.
  const Vec3d utm(512345.678, 5301234.567, 431.0);
  Sim3d model_from_true;
  model_from_true.scale = 0.05;
  model_from_true.rotation = LookAt(Vec3d(0.0), Vec3d(0.3, -0.2, 1.0), Vec3d(0.1, 1.0, 0.2)).rotation;
  model_from_true.translation = Vec3d(3.0, -1.0, 2.5);
  const double noise[8][2] = {{0.1, -0.2}, {-0.25, 0.1}, {0.2, 0.05}, {-0.1, -0.15},
                              {0.15, 0.2}, {-0.2, -0.05}, {0.05, 0.25}, {0.0, -0.1}};
  LightField light_field;
  std::vector<std::string> names;
  std::vector<NamedPosition> positions;
  std::vector<Rigid3d> truth;
  for (int k = 0; k < 8; ++k) {
    // Local, about the line's mean; the flight itself wavers by centimetres.
    const Vec3d centre(10.0 * k - 35.0, 0.03 * std::sin(1.7 * k), 0.02 * std::cos(2.3 * k));
    truth.push_back(NadirCamFromWorld(centre));
    View view;
    view.cam_from_world = TransformCamFromWorld(model_from_true, truth.back());
    light_field.views.push_back(view);
    names.push_back("f" + std::to_string(k) + ".png");
    positions.push_back({names.back(), utm + centre + Vec3d(0.0, noise[k][0], noise[k][1])});
  }
  // What the plain fit does with this noise: the roll is whatever the noise says.
  std::vector<Vec3d> model_centres, local;
  Vec3d mean(0.0);
  for (const NamedPosition& p : positions) mean += p.position / 8.0;
  for (int k = 0; k < 8; ++k) {
    model_centres.push_back(light_field.views[k].cam_from_world.Center());
    local.push_back(positions[k].position - mean);
  }
  const Sim3d plain = EstimateSimilarity(model_centres, local, "plain").dst_from_src;
  EXPECT_GT(AxisAngleDeg(TransformCamFromWorld(plain, light_field.views[0].cam_from_world),
                         truth[0]),
            10.0);

  const GeoreferenceResult result = Georeference(&light_field, names, positions, "gps.csv");
  EXPECT_TRUE(result.roll_from_down_prior);
  EXPECT_LT(result.width, kNearlyCollinearWidth);
  EXPECT_THAT(result.warning, HasSubstr("gps.csv: the positions lie nearly on a line"));
  for (int k = 0; k < 8; ++k) {
    EXPECT_LT(AxisAngleDeg(light_field.views[k].cam_from_world, truth[k]), 1.0) << k;
  }
  EXPECT_LT(result.rms_m, 0.3);
}

TEST(Georeference, CamerasLookingAlongTheirLineAreRefused) {
  std::vector<Vec3d> src, dst;
  for (int k = 0; k < 5; ++k) {
    src.push_back(Vec3d(k, 0.0, 0.0));
    dst.push_back(Vec3d(2.0 * k, 0.0, 0.0));
  }
  EXPECT_THAT(ErrorOf([&] {
                EstimateSimilarityOnLine(src, dst, Vec3d(1.0, 0.0, 0.01), Vec3d(0, 0, -1), "gps");
              }),
              HasSubstr("gps: the points lie on a line and the cameras look along it"));
  const SimilarityResult fit =
      EstimateSimilarityOnLine(src, dst, Vec3d(0.0, 0.0, 1.0), Vec3d(0, 0, -1), "gps");
  EXPECT_NEAR(fit.dst_from_src.scale, 2.0, 1e-12);
  EXPECT_LT(glm::length(fit.dst_from_src * Vec3d(0.0, 0.0, 1.0) - fit.dst_from_src * Vec3d(0.0) -
                        Vec3d(0.0, 0.0, -2.0)),
            1e-9);
  EXPECT_LT(fit.rms_residual, 1e-12);
}

TEST(Georeference, AnIncomingOriginIsAccountedFor) {
  // The same model, but its light field already has an origin (world = origin + local).
  ModelFrameLightField m = MakeModelFrameLightField(8.0);
  const Vec3d incoming(120.0, -40.0, 7.5);
  for (View& view : m.light_field.views) {
    view.cam_from_world.translation += view.cam_from_world.rotation * incoming;  // local shift
  }
  m.light_field.origin = incoming;
  const GeoreferenceResult result = Georeference(&m.light_field, m.names, m.positions, "gps.csv");
  EXPECT_LT(result.rms_m, 1e-9);
  for (size_t k = 0; k < m.true_local.size(); ++k) {
    EXPECT_LT(glm::length(m.light_field.views[k].cam_from_world.Center() - m.true_local[k].Center()),
              1e-8);
  }
}

TEST(Georeference, PositionsMatchFramesByPathOrFileName) {
  std::vector<std::string> warnings;
  const std::vector<std::string> frames = {"a/1.png", "a/2.png", "b/3.png", "b/1.png"};
  const std::vector<NamedPosition> given = {
      {"a/1.png", Vec3d(1, 0, 0)}, {"2.png", Vec3d(2, 0, 0)}, {"3.png", Vec3d(3, 0, 0)},
      {"1.png", Vec3d(9, 9, 9)},  // ambiguous file name: matches nothing
      {"z.png", Vec3d(4, 0, 0)}};
  const std::vector<NamedPosition> matched = MatchPositionsToFrames(given, frames, "gps.csv", &warnings);
  ASSERT_EQ(matched.size(), 3u);
  EXPECT_EQ(matched[0].name, "a/1.png");
  EXPECT_EQ(matched[1].name, "a/2.png");
  EXPECT_EQ(matched[2].name, "b/3.png");
  EXPECT_THAT(warnings, ElementsAre(HasSubstr("gps.csv: 2 position(s) name no frame: 1.png, z.png")));
  EXPECT_THAT(ErrorOf([&] { MatchPositionsToFrames({given[0], given[1]}, frames, "gps.csv", nullptr); }),
              HasSubstr("gps.csv: only 2 positions name a frame"));
  EXPECT_THAT(ErrorOf([&] {
                MatchPositionsToFrames({given[0], given[1], given[2], {"a/1.png", Vec3d(0.0)}},
                                       frames, "gps.csv", nullptr);
              }),
              HasSubstr("two positions name frame a/1.png"));
}

TEST(Georeference, TooFewOrDegeneratePositionsAreRefused) {
  ModelFrameLightField m = MakeModelFrameLightField(8.0);
  std::vector<NamedPosition> two(m.positions.begin(), m.positions.begin() + 2);
  EXPECT_THAT(ErrorOf([&] { Georeference(&m.light_field, m.names, two, "gps.csv"); }),
              HasSubstr("gps.csv: only 2 registered frames have a position"));
  // All centres on one line: orientation about that line is unknown.
  std::vector<NamedPosition> line = m.positions;
  for (size_t k = 0; k < line.size(); ++k) line[k].position = Vec3d(500000.0 + k, 5300000.0, 400.0);
  EXPECT_THAT(ErrorOf([&] { Georeference(&m.light_field, m.names, line, "gps.csv"); }),
              HasSubstr("gps.csv: target points are collinear"));
}

TEST(Georeference, TinyBaselinesStayAccurateOrAreRefused) {
  // 5 cm between frames at UTM coordinates: still solvable in double (centred first).
  ModelFrameLightField m = MakeModelFrameLightField(0.05);
  const GeoreferenceResult result = Georeference(&m.light_field, m.names, m.positions, "gps.csv");
  EXPECT_LT(result.rms_m, 1e-9);
  for (size_t k = 0; k < m.true_local.size(); ++k) {
    EXPECT_LT(glm::length(m.light_field.views[k].cam_from_world.Center() - m.true_local[k].Center()),
              1e-8);
  }
  // Coincident positions carry no scale or orientation at all.
  ModelFrameLightField same = MakeModelFrameLightField(8.0);
  for (NamedPosition& p : same.positions) p.position = Vec3d(500000.0, 5300000.0, 400.0);
  EXPECT_THAT(ErrorOf([&] { Georeference(&same.light_field, same.names, same.positions, "gps.csv"); }),
              HasSubstr("gps.csv: target points are coincident"));
}

class PosesPipeline : public testing_util::TempFolderTest {
 protected:
  void WriteFrame(const std::string& name, int width, int height) {
    std::filesystem::create_directories(std::filesystem::path(Path(name)).parent_path());
    Image image(width, height, 1, PixelType::kU8);
    WriteImage(Path(name), image);
  }
  // A stand-in COLMAP that prints a line and exits with `status`.
  std::string FakeColmap(int status) {
    const std::string path = Path("fake_colmap.sh");
    std::ofstream(path) << "#!/bin/sh\necho \"fake colmap: $1\"\nexit " << status << "\n";
    std::filesystem::permissions(path, std::filesystem::perms::owner_all);
    return path;
  }
};

TEST_F(PosesPipeline, OptionsAreChecked) {
  PosesOptions options;
  options.matcher = "vocab_tree";
  EXPECT_THAT(ErrorOf([&] { options.Check(); }), HasSubstr("matcher: must be one of sequential, spatial or exhaustive, got 'vocab_tree'"));
  options = PosesOptions();
  options.matcher = "spatial";
  EXPECT_THAT(ErrorOf([&] { options.Check(); }), HasSubstr("matcher: spatial matching needs positions"));
  options = PosesOptions();
  options.camera_model = "FOV";
  EXPECT_THAT(ErrorOf([&] { options.Check(); }), HasSubstr("camera_model: must be one of SIMPLE_PINHOLE, PINHOLE, SIMPLE_RADIAL, RADIAL, OPENCV, OPENCV_FISHEYE, SIMPLE_RADIAL_FISHEYE or RADIAL_FISHEYE, got 'FOV'"));
  options = PosesOptions();
  options.min_registered_fraction = 0.0;
  EXPECT_THAT(ErrorOf([&] { options.Check(); }), HasSubstr("min_registered_fraction"));
  options = PosesOptions();
  options.positions_file = "gps.csv";
  options.exif_positions = true;
  EXPECT_THAT(ErrorOf([&] { options.Check(); }), HasSubstr("give one source of positions"));
  options = PosesOptions();
  options.fov_deg = 200.0;
  EXPECT_THAT(ErrorOf([&] { options.Check(); }), HasSubstr("fov_deg"));
  options = PosesOptions();
  options.flight_height_m = -1.0;
  EXPECT_THAT(ErrorOf([&] { options.Check(); }), HasSubstr("flight_height_m: must be >= 0"));
  options.flight_height_m = std::nan("");
  EXPECT_THAT(ErrorOf([&] { options.Check(); }), HasSubstr("flight_height_m: must be >= 0"));
  options = PosesOptions();
  options.max_scale_deviation = 0.0;
  EXPECT_THAT(ErrorOf([&] { options.Check(); }), HasSubstr("max_scale_deviation: must be > 0"));
}

TEST_F(PosesPipeline, BadFoldersAndMissingColmapAreClearErrors) {
  PosesOptions options;
  options.colmap = FakeColmap(0);
  EXPECT_THAT(ErrorOf([&] { EstimatePoses(Path("missing"), options); }),
              HasSubstr("missing: not a folder of frames"));
  std::filesystem::create_directories(Path("empty"));
  EXPECT_THAT(ErrorOf([&] { EstimatePoses(Path("empty"), options); }),
              HasSubstr("empty: no readable frames"));
  WriteFrame("mixed/a.png", 32, 24);
  WriteFrame("mixed/b.png", 32, 24);
  WriteFrame("mixed/c.png", 24, 32);
  EXPECT_THAT(ErrorOf([&] { EstimatePoses(Path("mixed"), options); }),
              HasSubstr("frames differ in size (one camera for all frames): a.png is 32x24 but "
                        "c.png (24x32)"));
  options.colmap = "/nonexistent/colmap";
  EXPECT_THAT(ErrorOf([&] { EstimatePoses(Path("mixed"), options); }),
              HasSubstr("colmap: \"/nonexistent/colmap\" not found"));
}

TEST_F(PosesPipeline, ColmapFailingIsReportedWithItsOutputAndLeavesNothingBehind) {
  WriteFrame("frames/a.png", 32, 24);
  WriteFrame("frames/b.png", 32, 24);
  std::ofstream(Path("frames/broken.png")) << "not a png";
  PosesOptions options;
  options.colmap = FakeColmap(1);
  options.workspace = Path("ws");
  EXPECT_THAT(ErrorOf([&] { EstimatePoses(Path("frames"), options); }),
              HasSubstr("COLMAP feature_extractor (features) failed with exit status 1; the end "
                        "of its output:; fake colmap: feature_extractor"));
  // The named workspace is kept (with the log); the frames are untouched.
  EXPECT_TRUE(std::filesystem::exists(Path("ws/colmap_features.log")));
  EXPECT_EQ(std::filesystem::file_size(Path("frames/broken.png")), 9u);
  // A used workspace is refused before anything runs.
  EXPECT_THAT(ErrorOf([&] { EstimatePoses(Path("frames"), options); }), HasSubstr("ws"));
}

// A stand-in COLMAP whose mapper copies prepared text models into the output folder: the
// pipeline's handling of partial registration and several models, without COLMAP.
class FakeMapper : public PosesPipeline {
 protected:
  // A text model registering `names` (identity rotations, centres (i, i^2, -10), one point
  // 10 m in front of each).
  void WriteModel(const std::string& folder, const std::vector<std::string>& names) {
    std::filesystem::create_directories(Path(folder));
    std::ofstream(Path(folder + "/cameras.txt")) << "1 PINHOLE 32 24 30 30 16 12\n";
    std::ofstream images(Path(folder + "/images.txt"));
    std::ofstream points(Path(folder + "/points3D.txt"));
    for (size_t i = 0; i < names.size(); ++i) {
      images << i + 1 << " 1 0 0 0 " << -static_cast<double>(i) << " "
             << -static_cast<double>(i * i) << " 10 1 " << names[i]
             << "\n16 12 " << i + 1 << "\n";
      points << i + 1 << " " << i << " " << i * i << " 0 255 255 255 0.5 " << i + 1 << " 0\n";
    }
  }
  // A database with COLMAP 3.8's position-prior columns, which the stand-in's feature_extractor
  // hands on (spatial priors are written when positions are given).
  void PrepareDatabase() {
    sqlite3* db = nullptr;
    ASSERT_EQ(sqlite3_open(Path("prepared.db").c_str(), &db), SQLITE_OK);
    ASSERT_EQ(sqlite3_exec(db, "CREATE TABLE images (name TEXT, prior_tx REAL, prior_ty REAL, "
                               "prior_tz REAL)", nullptr, nullptr, nullptr),
              SQLITE_OK);
    sqlite3_close(db);
  }
  std::string Mapper() {
    const std::string path = Path("fake_mapper.sh");
    std::ofstream(path) << "#!/bin/sh\n"
                           "[ \"$1\" = feature_extractor ] && [ -f " << Path("prepared.db")
                        << " ] && cp " << Path("prepared.db") << " \"$3\"\n"
                           "[ \"$1\" = mapper ] || exit 0\n"
                           "while [ $# -gt 0 ]; do [ \"$1\" = --output_path ] && out=$2; shift; done\n"
                           "cp -r " << Path("models") << "/. \"$out\"\n";
    std::filesystem::permissions(path, std::filesystem::perms::owner_all);
    return path;
  }
  void Frames(int count) {
    for (int i = 0; i < count; ++i) WriteFrame("frames/f" + std::to_string(i) + ".png", 32, 24);
  }
};

TEST_F(FakeMapper, PartialRegistrationIsListedAndUsable) {
  Frames(5);
  std::ofstream(Path("frames/broken.png")) << "not a png";
  WriteModel("models/0", {"f0.png", "f1.png", "f2.png"});
  PosesOptions options;
  options.colmap = Mapper();
  const PosesResult result = EstimatePoses(Path("frames"), options);
  EXPECT_EQ(result.registered, (std::vector<std::string>{"f0.png", "f1.png", "f2.png"}));
  EXPECT_EQ(result.unregistered, (std::vector<std::string>{"f3.png", "f4.png"}));
  EXPECT_THAT(result.warnings, ElementsAre(HasSubstr("skipped 1 unreadable frame(s): broken.png"),
                                           HasSubstr("2 of 5 frames were not registered: f3.png, f4.png"),
                                           HasSubstr("focal length (30.0 px, a 56.1-degree field "
                                                     "of view) could not be checked")));
  ASSERT_TRUE(result.light_field.pose_source.has_value());
  EXPECT_EQ(result.light_field.pose_source->unregistered, result.unregistered);
  EXPECT_DOUBLE_EQ(result.mean_reprojection_error_px, 0.5);
  // Median depth 10 (the points lie 10 m in front), e = 0.5 px * 10 / 30 px.
  EXPECT_NEAR(result.median_depth, 10.0, 1e-9);
  EXPECT_NEAR(result.pose_error, 0.5 * 10.0 / 30.0, 1e-12);
  // Below the stated fraction it is an error naming the frames left out.
  options.min_registered_fraction = 0.7;
  EXPECT_THAT(ErrorOf([&] { EstimatePoses(Path("frames"), options); }),
              HasSubstr("COLMAP registered only 3 of 5 frames (below min_registered_fraction "
                        "0.7); not registered: f3.png, f4.png"));
}

TEST_F(FakeMapper, ImplausibleSelfCalibrationIsRefusedOrFlagged) {
  // The stand-in model's camera: fx = 30 px on 32-pixel-wide frames, a 56.1-degree field of view.
  Frames(3);
  WriteModel("models/0", {"f0.png", "f1.png", "f2.png"});
  PosesOptions options;
  options.colmap = Mapper();
  // No prior: kept, with a warning that the intrinsics could not be checked.
  PosesResult result = EstimatePoses(Path("frames"), options);
  EXPECT_THAT(result.warnings, ::testing::Contains(HasSubstr("could not be checked")));
  EXPECT_TRUE(std::isnan(result.focal_deviation));
  EXPECT_FALSE(result.implausible);
  // The right prior: checked and fine.
  options.fov_deg = 2.0 * std::atan(16.0 / 30.0) * 180.0 / M_PI;
  result = EstimatePoses(Path("frames"), options);
  EXPECT_NEAR(result.focal_prior_px, 30.0, 1e-9);
  EXPECT_NEAR(result.focal_deviation, 0.0, 1e-9);
  EXPECT_FALSE(result.implausible);
  // A 40-degree prior (fx 44 px): 32 % off, refused; kept with allow_implausible, loudly.
  options.fov_deg = 40.0;
  EXPECT_THAT(ErrorOf([&] { EstimatePoses(Path("frames"), options); }),
              HasSubstr("IMPLAUSIBLE self-calibration: the focal length came out at 30.0 px"));
  options.allow_implausible = true;
  result = EstimatePoses(Path("frames"), options);
  EXPECT_TRUE(result.implausible);
  EXPECT_NEAR(result.focal_deviation, 30.0 / (16.0 / std::tan(20.0 * M_PI / 180.0)) - 1.0, 1e-9);
  EXPECT_THAT(result.warnings, ::testing::Contains(HasSubstr("IMPLAUSIBLE")));
}

TEST_F(FakeMapper, SceneScaleIsCheckedAgainstTheFlightHeight) {
  // Positions at twice the model's camera centres (i, i^2, -10): geo-referencing scales the
  // model by 2, so the points 10 model units in front of the cameras lie 20 m below them.
  Frames(3);
  WriteModel("models/0", {"f0.png", "f1.png", "f2.png"});
  std::ofstream(Path("gps.csv")) << "f0.png,500000,5300000,100\nf1.png,500002,5300002,100\n"
                                    "f2.png,500004,5300008,100\n";
  PosesOptions options;
  options.positions_file = Path("gps.csv");
  // The right height: checked and fine.
  options.flight_height_m = 20.0;
  PosesResult result = ImportColmapPoses(Path("models/0"), Path("frames"), options);
  ASSERT_TRUE(result.georeferenced);
  EXPECT_NEAR(result.median_depth, 20.0, 1e-6);
  // The model's points come along in the local frame (what the ground estimate is made of).
  const ColmapModel model = ReadColmapModel(Path("models/0"));
  ASSERT_EQ(result.point_positions.size(), model.points.size());
  ASSERT_EQ(result.point_positions.size(), result.points);
  for (size_t i = 0; i < model.points.size(); ++i) {
    const Vec3d expected = result.local_from_model * model.points[i].position;
    EXPECT_LT(glm::length(result.point_positions[i] - expected), 1e-9);
  }
  EXPECT_NEAR(result.scale_deviation, 0.0, 1e-6);
  EXPECT_FALSE(result.implausible);
  EXPECT_THAT(result.warnings, ::testing::Not(::testing::Contains(HasSubstr("scene scale"))));
  // Within max_scale_deviation (20 / 18 = 1.11 < 1.15, 20 / 22.5 = 1 / 1.125): kept.
  options.flight_height_m = 18.0;
  EXPECT_FALSE(ImportColmapPoses(Path("models/0"), Path("frames"), options).implausible);
  options.flight_height_m = 22.5;
  EXPECT_FALSE(ImportColmapPoses(Path("models/0"), Path("frames"), options).implausible);
  // A 14 m flight read as 20 m deep (+43 %): refused naming both figures, or kept loudly.
  options.flight_height_m = 14.0;
  EXPECT_THAT(ErrorOf([&] { ImportColmapPoses(Path("models/0"), Path("frames"), options); }),
              HasSubstr("IMPLAUSIBLE scene scale: the views' median depth came out at 20.0 m but "
                        "the flight height is 14 m (1.43 times it, outside 1/(1 + d)..1 + d for "
                        "max_scale_deviation d = 0.15)"));
  options.max_scale_deviation = 0.5;  // a documented threshold, changeable
  EXPECT_FALSE(ImportColmapPoses(Path("models/0"), Path("frames"), options).implausible);
  options.max_scale_deviation = 0.15;
  options.allow_implausible = true;
  result = ImportColmapPoses(Path("models/0"), Path("frames"), options);
  EXPECT_TRUE(result.implausible);
  EXPECT_NEAR(result.scale_deviation, 20.0 / 14.0 - 1.0, 1e-6);
  EXPECT_THAT(result.warnings, ::testing::Contains(HasSubstr("IMPLAUSIBLE scene scale")));
  // Too deep a scene the other way: a 30 m flight read as 20 m.
  options.allow_implausible = false;
  options.flight_height_m = 30.0;
  EXPECT_THAT(ErrorOf([&] { ImportColmapPoses(Path("models/0"), Path("frames"), options); }),
              HasSubstr("(0.67 times it, outside 1/(1 + d)..1 + d"));
  // Self-calibrated and geo-referenced without a flight height: the scale is said unchecked.
  options.flight_height_m = 0.0;
  options.colmap = Mapper();
  PrepareDatabase();
  result = EstimatePoses(Path("frames"), options);
  EXPECT_TRUE(std::isnan(result.scale_deviation));
  EXPECT_THAT(result.warnings, ::testing::Contains(HasSubstr(
                                   "the scene scale (median depth 20.0 m) was not checked")));
  // With the flight height the pipeline checks it too.
  options.flight_height_m = 14.0;
  EXPECT_THAT(ErrorOf([&] { EstimatePoses(Path("frames"), options); }),
              HasSubstr("IMPLAUSIBLE scene scale"));
}

TEST_F(FakeMapper, AFlightHeightNeedsPositions) {
  // Without positions the model's units are arbitrary: refused before anything runs.
  Frames(3);
  WriteModel("models/0", {"f0.png", "f1.png", "f2.png"});
  PosesOptions options;
  options.flight_height_m = 20.0;
  options.colmap = FakeColmap(1);  // would fail if it ran
  EXPECT_THAT(ErrorOf([&] { ImportColmapPoses(Path("models/0"), Path("frames"), options); }),
              HasSubstr("flight_height_m: checks a geo-referenced model's scale, which needs "
                        "positions (positions_file or exif_positions)"));
  EXPECT_THAT(ErrorOf([&] { EstimatePoses(Path("frames"), options); }),
              HasSubstr("flight_height_m: checks a geo-referenced model's scale"));
  options.exif_positions = true;
  EXPECT_NO_THROW(options.Check());
}

TEST_F(FakeMapper, TheLargestOfSeveralModelsIsUsed) {
  Frames(5);
  WriteModel("models/0", {"f0.png", "f1.png"});
  WriteModel("models/1", {"f2.png", "f3.png", "f4.png"});
  PosesOptions options;
  options.colmap = Mapper();
  const PosesResult result = EstimatePoses(Path("frames"), options);
  EXPECT_EQ(result.models, 2);
  EXPECT_EQ(result.registered, (std::vector<std::string>{"f2.png", "f3.png", "f4.png"}));
  EXPECT_THAT(result.warnings, ::testing::Contains(HasSubstr("COLMAP built 2 separate models")));
  // The same model imported directly, geo-referenced by a positions file.
  std::ofstream(Path("gps.csv")) << "f2.png,500000,5300000,100\nf3.png,500002,5300000,100\n"
                                    "f4.png,500004,5300001,100\n";
  options.positions_file = Path("gps.csv");
  options.min_registered_fraction = 0.5;
  const PosesResult imported = ImportColmapPoses(Path("models/1"), Path("frames"), options);
  EXPECT_TRUE(imported.georeferenced);
  EXPECT_EQ(imported.unregistered, (std::vector<std::string>{"f0.png", "f1.png"}));
  EXPECT_NEAR(imported.light_field.origin.x, 500002.0, 1e-6);
  // Metres in an unstated frame: no EPSG code, the frame described in the pose record.
  EXPECT_EQ(imported.light_field.crs, "");
  EXPECT_EQ(imported.light_field.pose_source->world_frame, "the frame of " + Path("gps.csv"));
  // With the CRS stated, the light field records it (and the pose record no longer describes
  // the frame); without positions there is none.
  options.positions_crs = "EPSG:25833";
  const PosesResult stated = ImportColmapPoses(Path("models/1"), Path("frames"), options);
  EXPECT_EQ(stated.light_field.crs, "EPSG:25833");
  EXPECT_EQ(stated.light_field.pose_source->world_frame, "");
  WriteLightField(Path("lf.json"), stated.light_field);
  EXPECT_EQ(LoadLightField(Path("lf.json"), {0.0, "", false}).light_field.crs, "EPSG:25833");
  options.positions_file.clear();
  options.positions_crs.clear();
  options.min_registered_fraction = 0.5;
  EXPECT_EQ(ImportColmapPoses(Path("models/1"), Path("frames"), options).light_field.crs, "");
}

TEST_F(FakeMapper, FloatFramesAndUnmatchedPositionsAreRefusedBeforeColmapRuns) {
  Frames(3);
  Image frame(32, 24, 1, PixelType::kF32);
  WriteImage(Path("frames/thermal.tif"), frame);
  PosesOptions options;
  options.colmap = FakeColmap(1);  // would fail if it ran
  EXPECT_THAT(ErrorOf([&] { EstimatePoses(Path("frames"), options); }),
              HasSubstr("COLMAP reads 8- and 16-bit frames only; convert these to 16-bit first: "
                        "thermal.tif"));
  std::filesystem::remove(Path("frames/thermal.tif"));
  std::ofstream(Path("gps.csv")) << "x.png,1,2,3\nf0.png,1,2,3\n";
  options.positions_file = Path("gps.csv");
  options.workspace = Path("ws");
  EXPECT_THAT(ErrorOf([&] { EstimatePoses(Path("frames"), options); }),
              HasSubstr("only 1 positions name a frame"));
  EXPECT_FALSE(std::filesystem::exists(Path("ws")));  // nothing was started
}

TEST(PosesPreset, QuickSetsTheFieldsLeftAtTheirDefaults) {
  PosesOptions options;
  EXPECT_EQ(WithPreset(options).max_image_size, 1600);  // "default" changes nothing
  options.preset = "fast";
  EXPECT_THAT(ErrorOf([&] { options.Check(); }), HasSubstr("preset: must be one of default or quick, got 'fast'"));
  options = PosesOptions();
  options.sift_first_octave = 1;
  EXPECT_THAT(ErrorOf([&] { options.Check(); }), HasSubstr("sift_first_octave: must be -1"));
  options = PosesOptions();
  options.spatial_neighbors = 0;
  EXPECT_THAT(ErrorOf([&] { options.Check(); }), HasSubstr("spatial_neighbors: must be >= 1"));
  options = PosesOptions();
  options.preset = "quick";
  PosesOptions quick = WithPreset(options);
  EXPECT_EQ(quick.max_image_size, 480);
  EXPECT_EQ(quick.max_num_features, 512);
  EXPECT_EQ(quick.sift_first_octave, 0);
  EXPECT_EQ(quick.sequential_overlap, 3);
  EXPECT_EQ(quick.spatial_neighbors, 8);
  EXPECT_EQ(quick.matcher, "sequential");  // no positions: spatial matching cannot run
  options.positions_file = "gps.csv";
  EXPECT_EQ(WithPreset(options).matcher, "spatial");
  // A field given another value keeps it.
  options.max_num_features = 4096;
  options.matcher = "exhaustive";
  quick = WithPreset(options);
  EXPECT_EQ(quick.max_num_features, 4096);
  EXPECT_EQ(quick.matcher, "exhaustive");
  EXPECT_EQ(quick.max_image_size, 480);
}

TEST_F(PosesPipeline, QuickPresetReachesColmap) {
  WriteFrame("frames/a.png", 32, 24);
  WriteFrame("frames/b.png", 32, 24);
  // A stand-in COLMAP that records its command lines and "succeeds" without writing anything.
  const std::string colmap = Path("recording_colmap.sh");
  std::ofstream(colmap) << "#!/bin/sh\necho \"$@\" >> " << Path("colmap_args.txt") << "\nexit 0\n";
  std::filesystem::permissions(colmap, std::filesystem::perms::owner_all);
  PosesOptions options;
  options.colmap = colmap;
  options.preset = "quick";
  EXPECT_THAT(ErrorOf([&] { EstimatePoses(Path("frames"), options); }),
              HasSubstr("COLMAP registered no frames"));
  std::ifstream in(Path("colmap_args.txt"));
  const std::string args((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  EXPECT_THAT(args, HasSubstr("--SiftExtraction.max_image_size 480"));
  EXPECT_THAT(args, HasSubstr("--SiftExtraction.max_num_features 512"));
  EXPECT_THAT(args, HasSubstr("--SiftExtraction.first_octave 0"));
  EXPECT_THAT(args, HasSubstr("sequential_matcher"));
  EXPECT_THAT(args, HasSubstr("--SequentialMatching.overlap 3"));
}

TEST_F(PosesPipeline, ColmapBuildingNoModelIsAnError) {
  WriteFrame("frames/a.png", 32, 24);
  WriteFrame("frames/b.png", 32, 24);
  PosesOptions options;
  options.colmap = FakeColmap(0);  // "succeeds" without writing anything
  EXPECT_THAT(ErrorOf([&] { EstimatePoses(Path("frames"), options); }),
              HasSubstr("COLMAP registered no frames"));
}

}  // namespace
}  // namespace aos
