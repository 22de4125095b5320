// Poses from telemetry (sfm/telemetry.h) against an analytic flight: positions in UTM to the
// millimetre, orientations to 0.01 degrees, the heading convention (a nadir camera with yaw 0
// has its image 'up' at true north), the altitude-outlier rule, bad input, EXIF/XMP tags.
#include "aos/sfm/telemetry.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <string>
#include <vector>

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include "aos/geometry/geodesy.h"
#include "aos/geometry/heightfield.h"
#include "aos/image/image_io.h"
#include "aos/lightfield/formats.h"
#include "aos/sfm/odm.h"
#include "aos/util/error.h"
#include "aos/util/file_util.h"
#include "aos/util/math.h"
#include "error_of.h"
#include "gps_frame.h"
#include "temp_folder.h"

namespace aos {
namespace {

using ::testing::HasSubstr;
using test_util::ErrorOf;

constexpr double kDeg = kPi / 180.0;

// The angle of the rotation between two cam_from_world rotations, degrees.
double AngleBetweenDeg(const Mat3d& a, const Mat3d& b) {
  const Mat3d d = a * glm::transpose(b);
  const double c = std::clamp((d[0][0] + d[1][1] + d[2][2] - 1.0) / 2.0, -1.0, 1.0);
  return std::acos(c) / kDeg;
}

// A true pose in UTM 33N, the grid's own axes: heading as a grid bearing (clockwise from +y),
// pitch and roll as the telemetry convention states them.
struct TruePose {
  Vec3d position;  // easting, northing, altitude
  double grid_heading_deg, pitch_deg, roll_deg;
};

// cam_from_world of a true pose, built from LookAt (image up = world up, or for a nadir view the
// heading's direction) and then the roll about the viewing axis (right side down > 0).
Mat3d TrueCamFromWorld(const TruePose& p) {
  const double h = p.grid_heading_deg * kDeg, t = p.pitch_deg * kDeg, r = p.roll_deg * kDeg;
  const Vec3d forward(std::sin(h) * std::cos(t), std::cos(h) * std::cos(t), std::sin(t));
  const Vec3d up = std::abs(p.pitch_deg + 90.0) < 1e-9 ? Vec3d(std::sin(h), std::cos(h), 0.0)
                                                        : Vec3d(0.0, 0.0, 1.0);
  const Mat3d level = LookAt(Vec3d(0.0), forward, up).rotation;
  const Vec3d x = Row(level, 0), y = Row(level, 1), z = Row(level, 2);
  return MatFromRows(std::cos(r) * x + std::sin(r) * y, -std::sin(r) * x + std::cos(r) * y, z);
}

class Telemetry : public testing_util::TempFolderTest {
 protected:
  TelemetryOptions options_;
  void SetUp() override {
    TempFolderTest::SetUp();
    std::filesystem::create_directories(dir_ / "frames");
  }
  void Frame(const std::string& name) {
    Image image(8, 6, 1, PixelType::kU8);
    WriteImage(Path("frames/" + name), image);
  }
  std::string Write(const std::string& name, const std::string& text) {
    std::ofstream(Path(name)) << text;
    return Path(name);
  }
  // A 3 x 4 grid flight 45 km east of zone 33's central meridian (meridian convergence about
  // 0.45 degrees, well above the tolerance), 20 m apart, altitudes 100..111 m, varied angles.
  std::vector<TruePose> Flight() {
    std::vector<TruePose> poses;
    const double headings[] = {0.0, 30.0, 95.0, 180.0, 270.0, -45.0};
    const double pitches[] = {-90.0, -60.0, -85.0, -90.0};
    const double rolls[] = {0.0, 2.0, -3.0};
    for (int i = 0; i < 12; ++i) {
      poses.push_back({Vec3d(545000.0 + 20.0 * (i % 3), 5318000.0 + 20.0 * (i / 3), 100.0 + i),
                       headings[i % 6], pitches[i % 4], rolls[i % 3]});
    }
    return poses;
  }
  // The telemetry a logger would write for `poses`: WGS84 degrees, heading from true north.
  std::string FlightCsv(const std::vector<TruePose>& poses) {
    std::string csv = "# synthetic flight\nframe,lat,lon,alt,yaw,pitch,roll\n";
    for (size_t i = 0; i < poses.size(); ++i) {
      const Vec3d geo =
          TransformPoints({poses[i].position}, "EPSG:32633", "EPSG:4326", "truth")[0];
      // grid bearing = true heading + (grid bearing of true north).
      const double yaw = poses[i].grid_heading_deg -
                         GridBearingOfNorth(geo.y, geo.x, "EPSG:32633", "truth") / kDeg;
      char line[256];
      std::snprintf(line, sizeof(line), "f%02zu.png,%.10f,%.10f,%.4f,%.8f,%.8f,%.8f\n", i, geo.y,
                    geo.x, geo.z, yaw, poses[i].pitch_deg, poses[i].roll_deg);
      csv += line;
      Frame("f" + std::string(i < 10 ? "0" : "") + std::to_string(i) + ".png");
    }
    return csv;
  }
};

TEST_F(Telemetry, CsvFlightMatchesTheTruth) {
  const std::vector<TruePose> truth = Flight();
  TelemetryOptions options;
  options.telemetry_file = Write("log.csv", FlightCsv(truth));
  options.fov_deg = 60.0;
  const TelemetryResult result = ImportTelemetry(Path("frames"), options);
  const LightField& lf = result.light_field;
  EXPECT_EQ(lf.crs, "EPSG:32633");
  EXPECT_EQ(result.source, "csv");
  EXPECT_TRUE(result.altitude_outliers.empty());
  ASSERT_EQ(lf.views.size(), truth.size());
  // The origin: a round point (100 m) near the mean position, z = 0 (local z = altitude).
  EXPECT_EQ(lf.origin, Vec3d(545000.0, 5318000.0, 0.0));
  EXPECT_GT(result.max_convergence_deg, 0.4);
  for (size_t i = 0; i < truth.size(); ++i) {
    SCOPED_TRACE(lf.views[i].name);
    const Vec3d centre = lf.views[i].cam_from_world.Center() + lf.origin;
    // Millimetres: the CSV's 1e-10 degrees are 0.01 mm; PROJ is exact to well below that.
    EXPECT_NEAR(centre.x, truth[i].position.x, 1e-3);
    EXPECT_NEAR(centre.y, truth[i].position.y, 1e-3);
    EXPECT_NEAR(centre.z, truth[i].position.z, 1e-3);
    EXPECT_LT(AngleBetweenDeg(lf.views[i].cam_from_world.rotation, TrueCamFromWorld(truth[i])),
              0.01);
    EXPECT_EQ(lf.views[i].camera.width, 8);
  }
  // Written and read back: the CRS and the poses survive.
  WriteLightField(Path("lf.json"), lf);
  LoadOptions load;
  load.load_images = false;
  const LightField back = LoadLightField(Path("lf.json"), load).light_field;
  EXPECT_EQ(back.crs, "EPSG:32633");
  EXPECT_EQ(back.pose_source->method, "telemetry");
  EXPECT_NEAR(back.views[5].cam_from_world.Center().x, lf.views[5].cam_from_world.Center().x,
              1e-9);
  // The views keep the names they were imported with (not the paths written, frames/f05.png),
  // also when written again from another folder.
  EXPECT_EQ(back.views[5].name, "f05.png");
  std::filesystem::create_directories(dir_ / "a" / "b");
  WriteLightField(Path("a/b/lf.json"), back);
  const LightField again = LoadLightField(Path("a/b/lf.json"), load).light_field;
  EXPECT_EQ(again.views[5].name, "f05.png");
  EXPECT_EQ(std::filesystem::path(again.views[5].image_path).lexically_normal(),
            std::filesystem::path(back.views[5].image_path).lexically_normal());
}

TEST_F(Telemetry, ANadirCameraWithYawZeroHasItsImageUpAtTrueNorth) {
  // Far from the central meridian (17.9 E in zone 33: convergence about 2.2 degrees), image up
  // (-camera y in world) must point at a point due north, as PROJ maps it.
  const double lat = 48.0, lon = 17.9;
  const UtmCoordinate here = UtmFromWgs84(lat, lon, 33);
  const UtmCoordinate north = UtmFromWgs84(lat + 0.001, lon, 33);
  const double bearing_of_north = std::atan2(north.easting - here.easting,
                                             north.northing - here.northing);
  const Mat3d world_from_cam = WorldFromCameraRotation(0.0, -90.0, 0.0, bearing_of_north);
  const Vec3d up = -world_from_cam[1];  // column 1: camera y (image down) in the world
  EXPECT_NEAR(std::atan2(up.x, up.y) / kDeg, bearing_of_north / kDeg, 0.01);
  EXPECT_LT(std::abs(bearing_of_north) / kDeg, 2.3);
  EXPECT_GT(std::abs(bearing_of_north) / kDeg, 2.0);
  EXPECT_NEAR(world_from_cam[2].z, -1.0, 1e-12);  // looking straight down
  // Without convergence, yaw 0 nadir is NadirCamFromWorld (image top towards +y) exactly, and
  // yaw 90 puts image up at east.
  EXPECT_LT(AngleBetweenDeg(glm::transpose(WorldFromCameraRotation(0.0, -90.0, 0.0)),
                            NadirCamFromWorld(Vec3d(0.0)).rotation),
            1e-9);
  const Vec3d east_up = -WorldFromCameraRotation(90.0, -90.0, 0.0)[1];
  EXPECT_NEAR(east_up.x, 1.0, 1e-12);
  // Pitch 0, yaw 90: looking east at the horizon, image up = world up.
  const Mat3d level = WorldFromCameraRotation(90.0, 0.0, 0.0);
  EXPECT_NEAR(level[2].x, 1.0, 1e-12);
  EXPECT_NEAR(-level[1].z, 1.0, 1e-12);
  // Positive roll turns the camera's right side down, so the scene turns the other way in the
  // image: a point level and to the camera's right (south, for a camera looking east) comes out
  // above the image centre (camera y, image down, < 0), by the roll angle.
  const Mat3d rolled = glm::transpose(WorldFromCameraRotation(90.0, 0.0, 5.0));
  const Vec3d in_camera = rolled * Vec3d(0.0, -10.0, 0.0);
  EXPECT_GT(in_camera.x, 0.0);  // to the right
  EXPECT_NEAR(std::atan2(-in_camera.y, in_camera.x) / kDeg, 5.0, 1e-9);  // above
}

TEST(TelemetryAltitude, OutliersAreReplacedByTheRunningMedianAndListed) {
  // A steady climb of 0.5 m per frame with a barometer spike (+30 m at frame 3) and a drop
  // (-20 m at frame 10); a climb is no outlier.
  std::vector<double> altitudes;
  for (int i = 0; i < 15; ++i) altitudes.push_back(100.0 + 0.5 * i);
  altitudes[3] += 30.0;
  altitudes[10] -= 20.0;
  std::vector<double> fixed = altitudes;
  const auto replaced = ReplaceAltitudeOutliers(&fixed, 5, 5.0);
  ASSERT_EQ(replaced.size(), 2u);
  EXPECT_EQ(replaced[0].first, 3u);
  EXPECT_EQ(replaced[1].first, 10u);
  // The median of frames 1..5 (100.5, 101, 131.5, 102, 102.5) is 102; of 8..12, 104.5.
  EXPECT_DOUBLE_EQ(replaced[0].second, 102.0);
  EXPECT_DOUBLE_EQ(fixed[3], 102.0);
  EXPECT_DOUBLE_EQ(replaced[1].second, 104.5);
  for (int i : {0, 1, 2, 4, 9, 11, 14}) EXPECT_EQ(fixed[i], altitudes[i]);
  // At the ends the window is shifted inside the flight: a spike at frame 0 is found too.
  std::vector<double> start = {150.0, 100.0, 100.0, 100.0, 100.0, 100.0};
  EXPECT_EQ(ReplaceAltitudeOutliers(&start, 5, 5.0).size(), 1u);
  EXPECT_EQ(start[0], 100.0);
  // Window 0: no rule.
  std::vector<double> off = altitudes;
  EXPECT_TRUE(ReplaceAltitudeOutliers(&off, 0, 5.0).empty());
  EXPECT_EQ(off, altitudes);
}

TEST_F(Telemetry, AltitudeOutliersInALogAreReportedPerFrame) {
  std::vector<TruePose> truth = Flight();
  for (TruePose& p : truth) p.position.z = 100.0;  // level flight
  std::string csv = FlightCsv(truth);
  // Frame f07 logged 40 m too high.
  const size_t at = csv.find("f07.png");
  const size_t alt = csv.find(",100.0000,", at);
  csv.replace(alt, 10, ",140.0000,");
  TelemetryOptions options;
  options.telemetry_file = Write("log.csv", csv);
  options.fov_deg = 60.0;
  const TelemetryResult result = ImportTelemetry(Path("frames"), options);
  ASSERT_EQ(result.altitude_outliers.size(), 1u);
  EXPECT_EQ(result.altitude_outliers[0].frame, "f07.png");
  EXPECT_NEAR(result.altitude_outliers[0].altitude_m, 140.0, 1e-9);
  EXPECT_NEAR(result.altitude_outliers[0].median_m, 100.0, 1e-9);
  EXPECT_NEAR(result.light_field.views[7].cam_from_world.Center().z, 100.0, 1e-6);
  // A deviation within the threshold is kept as given.
  options.max_altitude_deviation_m = 50.0;
  EXPECT_TRUE(ImportTelemetry(Path("frames"), options).altitude_outliers.empty());
}

TEST_F(Telemetry, ATimeColumnIsInterpolatedAtTheFrameTimes) {
  Frame("a.png");
  Frame("b.png");
  Frame("c.png");
  // Rows at 0, 1, 2 s; frames every 0.5 s from t = 0.5: a at 0.5, b at 1.0, c at 1.5. The yaw
  // goes 350 -> 10 along the short arc (through 0, not 180).
  TelemetryOptions options;
  options.telemetry_file = Write("log.csv",
                                 "time,lat,lon,alt,yaw,pitch,roll\n"
                                 "0,48.0,15.0,100,350,-90,0\n"
                                 "1,48.001,15.0,110,10,-90,0\n"
                                 "2,48.002,15.0,120,30,-90,0\n");
  options.fov_deg = 60.0;
  options.frame_interval_s = 0.5;
  options.time_offset_s = 0.5;
  const TelemetryResult result = ImportTelemetry(Path("frames"), options);
  ASSERT_EQ(result.light_field.views.size(), 3u);
  const LightField& lf = result.light_field;
  EXPECT_NEAR(lf.views[0].cam_from_world.Center().z, 105.0, 1e-9);
  EXPECT_NEAR(lf.views[2].cam_from_world.Center().z, 115.0, 1e-9);
  const Vec3d mid = TransformPoints({Vec3d(15.0, 48.0005, 0.0)}, "EPSG:4326", "EPSG:32633", "t")[0];
  EXPECT_NEAR(lf.views[0].cam_from_world.Center().y + lf.origin.y, mid.y, 1e-3);
  // On the central meridian: a's yaw 0 is NadirCamFromWorld.
  EXPECT_LT(AngleBetweenDeg(lf.views[0].cam_from_world.rotation,
                            NadirCamFromWorld(Vec3d(0.0)).rotation),
            1e-6);
  // Frames beyond the log, and a time column without the interval, are refused.
  options.time_offset_s = 1.5;
  EXPECT_THAT(ErrorOf([&] { ImportTelemetry(Path("frames"), options); }),
              HasSubstr("log.csv: frame c.png at time 2.5 s lies outside the log's times [0, 2]"));
  options.frame_interval_s = 0.0;
  EXPECT_THAT(ErrorOf([&] { ImportTelemetry(Path("frames"), options); }),
              HasSubstr("log.csv: a time column needs frame_interval_s"));
}

TEST_F(Telemetry, BadInputIsOneErrorNamingFileLineAndField) {
  Frame("a.png");
  Frame("b.png");
  TelemetryOptions options;
  options.fov_deg = 60.0;
  const auto error = [&](const std::string& csv) {
    options.telemetry_file = Write("t.csv", csv);
    return ErrorOf([&] { ImportTelemetry(Path("frames"), options); });
  };
  const std::string header = "frame,lat,lon,alt,yaw,pitch,roll\n";
  EXPECT_THAT(error("frame,lat,lon,alt,yaw,pitch\na.png,48,15,100,0,-90\n"),
              HasSubstr("t.csv: line 1: the header has no roll column"));
  EXPECT_THAT(error("frame,lat,lon,alt,yaw,pitch,roll,speed\n"),
              HasSubstr("t.csv: line 1: column 8 \"speed\" is not one of"));
  EXPECT_THAT(error("lat,lon,alt,yaw,pitch,roll\n"),
              HasSubstr("t.csv: line 1: the header needs a frame column"));
  EXPECT_THAT(error(header + "a.png,48,15,100,0,-90,0\nb.png,abc,15,100,0,-90,0\n"),
              HasSubstr("t.csv: line 3: lat: \"abc\" is not a number"));
  EXPECT_THAT(error(header + "a.png,95,15,100,0,-90,0\n"),
              HasSubstr("t.csv: line 2: lat: 95 is outside [-90, 90] degrees"));
  EXPECT_THAT(error(header + "a.png,48,200,100,0,-90,0\n"),
              HasSubstr("t.csv: line 2: lon: 200 is outside [-180, 180] degrees"));
  EXPECT_THAT(error(header + "a.png,48,15,100,0,-90,nan\n"),
              HasSubstr("t.csv: line 2: roll: nan is not finite"));
  EXPECT_THAT(error(header + "a.png,48,15,100,0,-90,0\nnope.png,48,15,100,0,-90,0\n"),
              HasSubstr("t.csv: line 3: frame: \"nope.png\" names no frame in"));
  EXPECT_THAT(error(header + "a.png,48,15,100,0,-90,0\na.png,48,15,100,0,-90,0\n"),
              HasSubstr("t.csv: line 3: frame: \"a.png\" is repeated"));
  EXPECT_THAT(error(header + "a.png,48,15,100,0,-90\n"),
              HasSubstr("t.csv: line 2: expected 7 comma-separated fields"));
  EXPECT_THAT(error("# only a comment\n"), HasSubstr("t.csv: no header line"));
  // A frame without a row is left out, with a warning naming it.
  options.telemetry_file = Write("t.csv", header + "a.png,48,15,100,0,-90,0\n");
  const TelemetryResult partial = ImportTelemetry(Path("frames"), options);
  EXPECT_EQ(partial.light_field.views.size(), 1u);
  EXPECT_THAT(partial.warnings, ::testing::Contains(HasSubstr("1 frame(s) have no row in")));
  // Options name their field.
  options.fov_deg = 0.0;
  EXPECT_THAT(ErrorOf([&] { ImportTelemetry(Path("frames"), options); }),
              HasSubstr("fov_deg: a camera is needed"));
  options.fov_deg = 60.0;
  options.altitude_window = 4;
  EXPECT_THAT(ErrorOf([&] { options.Check(); }), HasSubstr("altitude_window: must be odd"));
}

// Inserts an XMP packet (an APP1 segment) after a JPEG's start-of-image marker.
void InjectXmp(const std::string& path, const std::string& packet) {
  std::ifstream in(path, std::ios::binary);
  std::string data((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  in.close();
  const std::string id = std::string("http://ns.adobe.com/xap/1.0/") + '\0';
  const size_t length = 2 + id.size() + packet.size();
  std::string segment = "\xFF\xE1";
  segment += static_cast<char>(length >> 8);
  segment += static_cast<char>(length & 0xFF);
  segment += id + packet;
  data.insert(2, segment);
  std::ofstream(path, std::ios::binary) << data;
}

std::string DjiXmp(double yaw, double pitch, double roll, double relative_altitude) {
  char text[1024];
  std::snprintf(text, sizeof(text),
                "<?xpacket begin=\"\" id=\"W5M0MpCehiHzreSzNTczkc9d\"?>"
                "<x:xmpmeta xmlns:x=\"adobe:ns:meta/\"><rdf:RDF "
                "xmlns:rdf=\"http://www.w3.org/1999/02/22-rdf-syntax-ns#\">"
                "<rdf:Description rdf:about=\"\" xmlns:drone-dji=\"http://www.dji.com/drone-dji/1.0/\" "
                "drone-dji:RelativeAltitude=\"%+.2f\" drone-dji:GimbalRollDegree=\"%+.2f\" "
                "drone-dji:GimbalYawDegree=\"%+.2f\">"
                "<drone-dji:GimbalPitchDegree>%+.2f</drone-dji:GimbalPitchDegree>"
                "</rdf:Description></rdf:RDF></x:xmpmeta><?xpacket end=\"w\"?>",
                relative_altitude, roll, yaw, pitch);
  return text;
}

TEST_F(Telemetry, ExifGpsAndDjiXmpTagsArePosesToo) {
  // Three JPEGs on the central meridian of zone 33, 0.0002 degrees (22 m) apart, with GPS
  // altitudes 350 m above the ellipsoid and XMP relative altitudes 30..32 m.
  for (int i = 0; i < 3; ++i) {
    const std::string path = Path("frames/d" + std::to_string(i) + ".jpg");
    ASSERT_TRUE(testing_util::WriteGpsTaggedFrame(path, 16, 12, 48.0 + 0.0002 * i, 15.0, 350.0));
    InjectXmp(path, DjiXmp(i == 1 ? 90.0 : 0.0, -90.0, 0.0, 30.0 + i));
  }
  TelemetryOptions options;
  options.fov_deg = 70.0;
  TelemetryResult result = ImportTelemetry(Path("frames"), options);
  EXPECT_EQ(result.source, "exif");
  EXPECT_EQ(result.light_field.crs, "EPSG:32633");
  ASSERT_EQ(result.light_field.views.size(), 3u);
  const LightField& lf = result.light_field;
  // EXIF stores the seconds as float rationals here: within 1e-6 degrees (0.1 m).
  const Vec3d truth = TransformPoints({Vec3d(15.0, 48.0002, 0.0)}, "EPSG:4326", "EPSG:32633", "t")[0];
  EXPECT_NEAR(lf.views[1].cam_from_world.Center().x + lf.origin.x, truth.x, 0.1);
  EXPECT_NEAR(lf.views[1].cam_from_world.Center().y + lf.origin.y, truth.y, 0.1);
  EXPECT_NEAR(lf.views[1].cam_from_world.Center().z, 31.0, 1e-9);  // auto: relative altitude
  // d1 has yaw 90: image up at east; d0 yaw 0: image up at north (central meridian).
  EXPECT_NEAR(-Row(lf.views[1].cam_from_world.rotation, 1).x, 1.0, 1e-9);
  EXPECT_NEAR(-Row(lf.views[0].cam_from_world.rotation, 1).y, 1.0, 1e-9);
  options.altitude = "gps";
  result = ImportTelemetry(Path("frames"), options);
  EXPECT_NEAR(result.light_field.views[1].cam_from_world.Center().z, 350.0, 1e-3);
  // A frame without the gimbal tags: an error naming it and the tag.
  ASSERT_TRUE(testing_util::WriteGpsTaggedFrame(Path("frames/e.jpg"), 16, 12, 48.0, 15.0, 350.0));
  EXPECT_THAT(ErrorOf([&] { ImportTelemetry(Path("frames"), options); }),
              HasSubstr("e.jpg: no XMP drone-dji:GimbalYawDegree (the frame has no XMP packet)"));
}

// The CSV of Flight() with frame `frame`'s lat and lon replaced by `lat_lon` ("lat,lon").
std::string WithPosition(std::string csv, const std::string& frame, const std::string& lat_lon) {
  const size_t at = csv.find(frame + ",");
  const size_t lat = at + frame.size() + 1;
  const size_t alt = csv.find(',', csv.find(',', lat) + 1);
  return csv.replace(lat, alt - lat, lat_lon);
}

TEST_F(Telemetry, APositionFarFromTheFlightIsRefusedNamingLineFrameAndDistance) {
  const std::vector<TruePose> truth = Flight();
  const std::string csv = FlightCsv(truth);
  TelemetryOptions options;
  options.fov_deg = 60.0;
  const auto error = [&](const std::string& text) {
    options.telemetry_file = Write("log.csv", text);
    return ErrorOf([&] { ImportTelemetry(Path("frames"), options); });
  };
  // f05 (line 8) at about 48.03 N, 15.60 E: swapped, in radians, in the other hemisphere. Each
  // is thousands of kilometres from the median of the flight, far beyond 50 km.
  const std::string swapped = error(WithPosition(csv, "f05.png", "15.6,48.03"));
  EXPECT_THAT(swapped, HasSubstr("log.csv: line 8 (frame f05.png): lat, lon: (15.6, 48.03) is "));
  EXPECT_THAT(swapped, HasSubstr("km from the flight's centre"));
  EXPECT_THAT(swapped, HasSubstr("max_distance_from_centre_m = 50000"));
  EXPECT_THAT(swapped, HasSubstr("latitude and longitude swapped?"));
  EXPECT_THAT(error(WithPosition(csv, "f05.png", "0.8383,0.2723")),
              HasSubstr("in radians, not degrees?"));
  EXPECT_THAT(error(WithPosition(csv, "f05.png", "-48.03,15.6")),
              HasSubstr("line 8 (frame f05.png): lat, lon: (-48.03, 15.6) is "));
  // Half the rows in the other hemisphere: the centre is between them, every row is refused.
  std::string half = csv;
  for (const char* frame : {"f00.png", "f01.png", "f02.png", "f03.png", "f04.png", "f05.png"}) {
    const size_t lat = half.find(std::string(frame) + ",") + 8;
    half.insert(lat, "-");
  }
  EXPECT_THAT(error(half), HasSubstr("km from the flight's centre"));
  // The bound is an option, checked: a flight that is truly that large is taken when asked.
  options.max_distance_from_centre_m = 1e7;
  EXPECT_THAT(error(WithPosition(csv, "f05.png", "15.6,48.03")), "no error");
  options.max_distance_from_centre_m = 0.0;
  EXPECT_THAT(ErrorOf([&] { options.Check(); }),
              HasSubstr("max_distance_from_centre_m: must be > 0 metres"));
  options.max_distance_from_centre_m = std::nan("");
  EXPECT_THAT(ErrorOf([&] { options.Check(); }), HasSubstr("max_distance_from_centre_m"));
}

TEST_F(Telemetry, ImplausibleAltitudesAreRefusedNamingTheField) {
  std::string csv = FlightCsv(Flight());
  const size_t at = csv.find("f03.png");
  const size_t alt = csv.find(",103.0000,", at);
  TelemetryOptions options;
  options.fov_deg = 60.0;
  options.telemetry_file = Write("log.csv", csv.replace(alt, 10, ",1e308,"));
  EXPECT_THAT(ErrorOf([&] { ImportTelemetry(Path("frames"), options); }),
              HasSubstr("log.csv: line 6: alt: 1e+308 is outside the plausible altitudes "
                        "[-5000, 10000] metres"));
}

// The antimeridian: a small flight at 16.5 S across longitude 180 (Fiji).
TEST_F(Telemetry, AFlightAcrossTheAntimeridianIsOneZoneAndMetresApart) {
  // Four frames 0.00002 degrees of longitude (2.13 m at 16.5 S) apart, crossing 180.
  const double longitudes[] = {179.99997, 179.99999, -179.99999, -179.99997};
  std::string csv = "frame,lat,lon,alt,yaw,pitch,roll\n";
  for (int i = 0; i < 4; ++i) {
    Frame("m" + std::to_string(i) + ".png");
    char line[128];
    std::snprintf(line, sizeof(line), "m%d.png,-16.5,%.5f,100,0,-90,0\n", i, longitudes[i]);
    csv += line;
  }
  TelemetryOptions options;
  options.fov_deg = 60.0;
  options.telemetry_file = Write("log.csv", csv);
  const TelemetryResult result = ImportTelemetry(Path("frames"), options);
  const LightField& lf = result.light_field;
  // One zone for the whole flight, one of the two that meet at 180 (south: EPSG:327zz).
  EXPECT_THAT(lf.crs, ::testing::AnyOf("EPSG:32760", "EPSG:32701"));
  ASSERT_EQ(lf.views.size(), 4u);
  // Consecutive views 2.13 m apart eastwards: 0.00002 deg x 111.32 km/deg x cos(16.5 deg), within
  // the UTM scale factor 3 degrees from the central meridian (0.9996 .. 1.0009) and the sphere's
  // approximation (0.5%); due east is turned from grid east by the convergence (0.85 degrees:
  // 2.13 m x sin 0.85 = 0.032 m of northing).
  const double spacing = 0.00002 * 111320.0 * std::cos(16.5 * kDeg);
  for (int i = 1; i < 4; ++i) {
    const Vec3d step = lf.views[i].cam_from_world.Center() - lf.views[i - 1].cam_from_world.Center();
    EXPECT_NEAR(step.x, spacing, 0.005 * spacing) << i;
    EXPECT_NEAR(std::abs(step.y), 0.032, 0.002) << i;
  }
  // The origin is near the flight, and grid north is within the convergence 3 degrees from a
  // central meridian: 3 x sin(16.5 deg) = 0.85 degrees.
  const Vec3d first = lf.views[0].cam_from_world.Center();  // local: origin rounded to 100 m
  EXPECT_LT(std::hypot(first.x, first.y), 71.0);
  EXPECT_NEAR(result.max_convergence_deg, 0.85, 0.01);
  // A time column interpolates the longitude along the shorter arc too (not through 0).
  options.telemetry_file = Write("time.csv",
                                 "time,lat,lon,alt,yaw,pitch,roll\n"
                                 "0,-16.5,179.99997,100,0,-90,0\n"
                                 "3,-16.5,-179.99997,100,0,-90,0\n");
  options.frame_interval_s = 1.0;
  const LightField timed = ImportTelemetry(Path("frames"), options).light_field;
  EXPECT_THAT(timed.crs, ::testing::AnyOf("EPSG:32760", "EPSG:32701"));
  for (int i = 0; i < 4; ++i) {
    EXPECT_NEAR(timed.views[i].cam_from_world.Center().x + timed.origin.x,
                lf.views[i].cam_from_world.Center().x + lf.origin.x, 0.01)
        << i;
  }
}

TEST_F(Telemetry, AFlightAcrossAZoneEdgeTakesTheZoneOfItsCentre) {
  // Zones 33 and 34 meet at 18 E. Three frames just west of it and one 300 m east: the median
  // longitude (17.9993) is in zone 33, the mean (18.00015) would be in 34. One zone for all.
  const double longitudes[] = {17.9990, 17.9992, 17.9994, 18.0030};
  std::string csv = "frame,lat,lon,alt,yaw,pitch,roll\n";
  for (int i = 0; i < 4; ++i) {
    Frame("z" + std::to_string(i) + ".png");
    csv += "z" + std::to_string(i) + ".png,48.0," + FormatNumber(longitudes[i]) + ",100,0,-90,0\n";
  }
  TelemetryOptions options;
  options.fov_deg = 60.0;
  options.telemetry_file = Write("log.csv", csv);
  const LightField lf = ImportTelemetry(Path("frames"), options).light_field;
  EXPECT_EQ(lf.crs, "EPSG:32633");
  const Vec3d truth =
      TransformPoints({Vec3d(18.0030, 48.0, 0.0)}, "EPSG:4326", "EPSG:32633", "t")[0];
  EXPECT_NEAR(lf.views[3].cam_from_world.Center().x + lf.origin.x, truth.x, 1e-3);
}

TEST_F(Telemetry, AByteOrderMarkAndQuotedFieldsAreRead) {
  Frame("a,b.png");
  Frame("say \"hi\".png");
  TelemetryOptions options;
  options.fov_deg = 60.0;
  options.telemetry_file = Write("log.csv",
                                 "\xEF\xBB\xBF" "frame,lat,lon,alt,yaw,pitch,roll\r\n"
                                 "\"a,b.png\",48.0,15.0,100,0,-90,0\r\n"
                                 "\"say \"\"hi\"\".png\",\"48.0001\",15.0,100,0,-90,0\r\n");
  const TelemetryResult result = ImportTelemetry(Path("frames"), options);
  ASSERT_EQ(result.light_field.views.size(), 2u);
  EXPECT_EQ(result.frames[0], "a,b.png");
  EXPECT_EQ(result.frames[1], "say \"hi\".png");
  // 0.0001 degrees of latitude apart: 11.1 m.
  EXPECT_NEAR(result.light_field.views[1].cam_from_world.Center().y -
                  result.light_field.views[0].cam_from_world.Center().y,
              11.1, 0.05);
  // A quote left open is one error naming the line it opened on.
  options.telemetry_file = Write("log.csv",
                                 "frame,lat,lon,alt,yaw,pitch,roll\n"
                                 "\"a,b.png,48.0,15.0,100,0,-90,0\n");
  EXPECT_THAT(ErrorOf([&] { ImportTelemetry(Path("frames"), options); }),
              HasSubstr("log.csv: line 2: field 1: its opening quote is never closed"));
}

// A JPEG with GPS tags whose hemisphere letters are given as they are (not from the signs).
std::string FrameWithGpsRefs(const std::string& path, const char* latitude_ref,
                             const char* longitude_ref,
                             std::array<float, 3> latitude = {48.0f, 0.0f, 0.0f},
                             std::array<float, 3> longitude = {15.0f, 0.0f, 0.0f}) {
  OIIO::ImageSpec spec(16, 12, 1, OIIO::TypeDesc::UINT8);
  spec.attribute("GPS:Latitude", OIIO::TypeDesc(OIIO::TypeDesc::FLOAT, 3), latitude.data());
  spec.attribute("GPS:LatitudeRef", latitude_ref);
  spec.attribute("GPS:Longitude", OIIO::TypeDesc(OIIO::TypeDesc::FLOAT, 3), longitude.data());
  spec.attribute("GPS:LongitudeRef", longitude_ref);
  spec.attribute("GPS:Altitude", 350.0f);
  std::vector<uint8_t> pixels(16 * 12, 128);
  auto output = OIIO::ImageOutput::create(path);
  EXPECT_TRUE(output && output->open(path, spec) &&
              output->write_image(OIIO::TypeDesc::UINT8, pixels.data()));
  output->close();
  return path;
}

TEST_F(Telemetry, HemisphereLettersOtherThanNSEWAreRefusedNamingTheTag) {
  const std::string good = FrameWithGpsRefs(Path("good.jpg"), "S", "W");
  const std::optional<GpsTag> tag = ReadGpsTag(good);
  ASSERT_TRUE(tag.has_value());
  EXPECT_NEAR(tag->latitude_deg, -48.0, 1e-9);
  EXPECT_NEAR(tag->longitude_deg, -15.0, 1e-9);
  EXPECT_THAT(ErrorOf([&] { ReadGpsTag(FrameWithGpsRefs(Path("x.jpg"), "X", "E")); }),
              HasSubstr("x.jpg: GPS:LatitudeRef: \"X\" is not N or S"));
  EXPECT_THAT(ErrorOf([&] { ReadGpsTag(FrameWithGpsRefs(Path("y.jpg"), "N", "S")); }),
              HasSubstr("y.jpg: GPS:LongitudeRef: \"S\" is not E or W"));
  // Through import-telemetry: the frame and the tag.
  FrameWithGpsRefs(Path("frames/z.jpg"), "N", "Q");
  InjectXmp(Path("frames/z.jpg"), DjiXmp(0.0, -90.0, 0.0, 30.0));
  TelemetryOptions options;
  options.fov_deg = 60.0;
  EXPECT_THAT(ErrorOf([&] { ImportTelemetry(Path("frames"), options); }),
              HasSubstr("z.jpg: GPS:LongitudeRef: \"Q\" is not E or W"));
}

// Found by tools/fuzz.py: 91 minutes or 3600 seconds were read as a position.
TEST_F(Telemetry, GpsAnglesWithMinutesOrSecondsOf60OrMoreAreRefused) {
  const std::optional<GpsTag> tag = ReadGpsTag(
      FrameWithGpsRefs(Path("ok.jpg"), "N", "E", {48.0f, 59.0f, 59.5f}, {180.0f, 0.0f, 0.0f}));
  ASSERT_TRUE(tag.has_value());
  EXPECT_NEAR(tag->latitude_deg, 48.0 + 59.0 / 60 + 59.5 / 3600, 1e-6);
  EXPECT_NEAR(tag->longitude_deg, 180.0, 1e-9);
  EXPECT_THAT(ErrorOf([&] {
                ReadGpsTag(FrameWithGpsRefs(Path("m.jpg"), "N", "E", {48.0f, 91.0f, 0.0f}));
              }),
              HasSubstr("m.jpg: GPS:Latitude: 48 deg 91' 0\" is not an angle of 0 to 90"));
  EXPECT_THAT(ErrorOf([&] {
                ReadGpsTag(FrameWithGpsRefs(Path("s.jpg"), "N", "E", {48.0f, 0.0f, 0.0f},
                                            {15.0f, 0.0f, 3600.0f}));
              }),
              HasSubstr("s.jpg: GPS:Longitude: 15 deg 0' 3600\" is not an angle of 0 to 180"));
  EXPECT_THAT(ErrorOf([&] {
                ReadGpsTag(FrameWithGpsRefs(Path("d.jpg"), "N", "E", {95.0f, 0.0f, 0.0f}));
              }),
              HasSubstr("d.jpg: GPS:Latitude: 95 deg"));
  // (A negative component cannot be written: EXIF stores unsigned rationals.)
}

TEST_F(Telemetry, ImplausibleTagAltitudesAreRefusedNamingTheTag) {
  const std::string path = Path("frames/d.jpg");
  ASSERT_TRUE(testing_util::WriteGpsTaggedFrame(path, 16, 12, 48.0, 15.0, 20000.0));
  InjectXmp(path, DjiXmp(0.0, -90.0, 0.0, -1e308));
  TelemetryOptions options;
  options.fov_deg = 60.0;
  EXPECT_THAT(ErrorOf([&] { ImportTelemetry(Path("frames"), options); }),
              HasSubstr("d.jpg: XMP drone-dji:RelativeAltitude: -1e+308 is outside the plausible "
                        "altitudes [-5000, 10000] metres"));
  options.altitude = "gps";
  EXPECT_THAT(ErrorOf([&] { ImportTelemetry(Path("frames"), options); }),
              HasSubstr("d.jpg: GPS:Altitude: 20000 is outside the plausible altitudes "
                        "[-500, 10000] metres"));
}

TEST_F(Telemetry, TagPositionsFarFromTheFlightAreRefusedNamingTheFrame) {
  for (int i = 0; i < 5; ++i) {
    const std::string path = Path("frames/d" + std::to_string(i) + ".jpg");
    // d3 in radians.
    const double lat = i == 3 ? 48.0 * kDeg : 48.0 + 0.0002 * i;
    const double lon = i == 3 ? 15.0 * kDeg : 15.0;
    ASSERT_TRUE(testing_util::WriteGpsTaggedFrame(path, 16, 12, lat, lon, 350.0));
    InjectXmp(path, DjiXmp(0.0, -90.0, 0.0, 30.0));
  }
  TelemetryOptions options;
  options.fov_deg = 60.0;
  const std::string message = ErrorOf([&] { ImportTelemetry(Path("frames"), options); });
  EXPECT_THAT(message, HasSubstr("d3.jpg: GPS:Latitude, GPS:Longitude: ("));
  EXPECT_THAT(message, HasSubstr("km from the flight's centre"));
  EXPECT_THAT(message, HasSubstr("in radians, not degrees?"));
}

// A straight flight north along zone 33's central meridian (x = 500000): frame k (1-based) at
// northing 5318000 + 10 k, altitude 100 + 0.5 k, yaw 0, nadir.
Vec3d StraightFlightPosition(int k) {
  return Vec3d(500000.0, 5318000.0 + 10.0 * k, 100.0 + 0.5 * k);
}

TEST_F(Telemetry, UnpaddedFrameNamesFollowATimeLogInCaptureOrder) {
  // Frames 1.png .. 25.png (no zero padding: in byte order 1, 10, 11, ..., 19, 2, 20, ...) and a
  // log with one row per second; frame k is at time k - 1. Frame 7's altitude is logged 20 m
  // high: the altitude rule must replace that one only.
  const int n = 25;
  std::string csv = "time,lat,lon,alt,yaw,pitch,roll\n";
  for (int k = 1; k <= n; ++k) {
    Frame(std::to_string(k) + ".png");
    const Vec3d p = StraightFlightPosition(k);
    const Vec3d geo = TransformPoints({p}, "EPSG:32633", "EPSG:4326", "truth")[0];
    char line[160];
    std::snprintf(line, sizeof(line), "%d,%.10f,%.10f,%.4f,0,-90,0\n", k - 1, geo.y, geo.x,
                  p.z + (k == 7 ? 20.0 : 0.0));
    csv += line;
  }
  TelemetryOptions options;
  options.telemetry_file = Write("log.csv", csv);
  options.fov_deg = 60.0;
  options.frame_interval_s = 1.0;
  const TelemetryResult result = ImportTelemetry(Path("frames"), options);
  EXPECT_EQ(result.order, "name");  // PNGs without EXIF times: natural name order
  const LightField& lf = result.light_field;
  ASSERT_EQ(lf.views.size(), static_cast<size_t>(n));
  for (int k = 1; k <= n; ++k) {
    const View& view = lf.views[k - 1];
    SCOPED_TRACE(view.name);
    EXPECT_EQ(view.name, std::to_string(k) + ".png");
    const Vec3d centre = view.cam_from_world.Center() + lf.origin;
    EXPECT_NEAR(centre.x, StraightFlightPosition(k).x, 1e-3);
    EXPECT_NEAR(centre.y, StraightFlightPosition(k).y, 1e-3);
    // Frame 7's glitch is replaced by its running median (104 below), 0.5 m above the truth on
    // this climb.
    EXPECT_NEAR(centre.z, k == 7 ? 104.0 : StraightFlightPosition(k).z, 1e-3);
  }
  ASSERT_EQ(result.altitude_outliers.size(), 1u);
  EXPECT_EQ(result.altitude_outliers[0].frame, "7.png");
  // The median of frames 3..11's given altitudes (7 excluded: 101.5 .. 105.5 and 123.5) is 104.
  EXPECT_NEAR(result.altitude_outliers[0].median_m, 104.0, 1e-6);
  EXPECT_TRUE(result.warnings.empty());
}

TEST(NaturalOrder, NumbersInNamesCompareAsNumbers) {
  std::vector<std::string> names = {"10.png", "2.png", "1.png", "frame_10b.png", "frame_9.png",
                                    "02.png", "a/10.png", "a/9.png", "B.png", "a.png"};
  SortNaturally(&names);
  EXPECT_EQ(names, (std::vector<std::string>{"1.png", "02.png", "2.png", "10.png", "B.png",
                                             "a.png", "a/9.png", "a/10.png", "frame_9.png",
                                             "frame_10b.png"}));
  EXPECT_FALSE(NaturalLess("x", "x"));
  EXPECT_TRUE(NaturalLess("img_0099", "img_100"));
  EXPECT_TRUE(NaturalLess("9", "00000000000000000000000010"));  // beyond 64-bit integers too
}

TEST_F(Telemetry, ExifCaptureTimesOrderTheViewsAndADisagreementIsNamed) {
  // a.jpg was taken 0.25 s after b.jpg, c.jpg last: views b, a, c, with a warning naming them.
  const struct {
    const char* name;
    const char* time;
    const char* subsec;
  } frames[] = {{"a.jpg", "2026:06:01 10:00:01", "25"},
                {"b.jpg", "2026:06:01 10:00:01", "0"},
                {"c.jpg", "2026:06:01 10:00:02", ""}};
  for (int i = 0; i < 3; ++i) {
    const std::string path = Path("frames/") + frames[i].name;
    ASSERT_TRUE(testing_util::WriteGpsTaggedFrame(path, 16, 12, 48.0 + 0.0002 * i, 15.0, 350.0,
                                                  frames[i].time, frames[i].subsec));
    InjectXmp(path, DjiXmp(0.0, -90.0, 0.0, 30.0 + i));
  }
  EXPECT_NEAR(*ReadCaptureTime(Path("frames/a.jpg")) - *ReadCaptureTime(Path("frames/b.jpg")),
              0.25, 1e-6);
  // 2026-06-01 is day 20605 after 1970-01-01.
  EXPECT_NEAR(*ReadCaptureTime(Path("frames/c.jpg")), 20605.0 * 86400.0 + 36002.0, 1e-6);
  TelemetryOptions options;
  options.fov_deg = 70.0;
  options.altitude = "gps";
  const TelemetryResult result = ImportTelemetry(Path("frames"), options);
  EXPECT_EQ(result.order, "time");
  EXPECT_EQ(result.time_source, "EXIF DateTimeOriginal");
  EXPECT_EQ(result.frames, (std::vector<std::string>{"b.jpg", "a.jpg", "c.jpg"}));
  EXPECT_EQ(result.light_field.views[0].name, "b.jpg");
  ASSERT_EQ(result.warnings.size(), 1u);
  EXPECT_THAT(result.warnings[0],
              HasSubstr("name order and capture-time order disagree (2 of 3 frames move): b.jpg "
                        "(at +0 s) was taken before a.jpg (at +0.25 s)"));
  // A malformed date is refused naming the frame and the tag.
  ASSERT_TRUE(testing_util::WriteGpsTaggedFrame(Path("frames/d.jpg"), 16, 12, 48.0, 15.0, 350.0,
                                                "June 1st"));
  EXPECT_THAT(ErrorOf([&] { ReadCaptureTime(Path("frames/d.jpg")); }),
              HasSubstr("d.jpg: Exif:DateTimeOriginal: \"June 1st\" is not a date and time"));
}

TEST_F(Telemetry, AFrameLogWithATimeColumnOrdersTheViewsByIt) {
  Frame("a.png");
  Frame("b.png");
  Frame("c.png");
  TelemetryOptions options;
  options.telemetry_file = Write("log.csv",
                                 "frame,time,lat,lon,alt,yaw,pitch,roll\n"
                                 "a.png,5,48.0,15.0,100,0,-90,0\n"
                                 "b.png,3,48.001,15.0,100,0,-90,0\n"
                                 "c.png,9,48.002,15.0,100,0,-90,0\n");
  options.fov_deg = 60.0;
  const TelemetryResult result = ImportTelemetry(Path("frames"), options);
  EXPECT_EQ(result.order, "time");
  EXPECT_THAT(result.time_source, HasSubstr("the time column of"));
  EXPECT_EQ(result.frames, (std::vector<std::string>{"b.png", "a.png", "c.png"}));
}

TEST_F(Telemetry, YawReferencesTurnTheHeadingByTheStatedCorrection) {
  // One frame at 48 N 17.9 E (zone 33, meridian convergence about 2.2 degrees), yaw 10, nadir.
  // Image up (-camera y) must point at grid bearing: true 10 + c; grid 10; magnetic with a
  // declination of +4 (east): 14 + c, where c = GridBearingOfNorth there.
  Frame("a.png");
  const double lat = 48.0, lon = 17.9;
  options_.telemetry_file = Write("log.csv", "frame,lat,lon,alt,yaw,pitch,roll\n"
                                             "a.png,48.0,17.9,100,10,-90,0\n");
  options_.fov_deg = 60.0;
  const double c = GridBearingOfNorth(lat, lon, "EPSG:32633", "truth") / kDeg;
  // The convergence is -(lon - 15) sin(lat) to first order (the sphere): -2.155 degrees here.
  EXPECT_NEAR(c, -(lon - 15.0) * std::sin(lat * kDeg), 0.01);
  const auto image_up_bearing = [&](const TelemetryResult& result) {
    const Vec3d up = -Row(result.light_field.views[0].cam_from_world.rotation, 1);
    return std::atan2(up.x, up.y) / kDeg;
  };
  TelemetryResult result = ImportTelemetry(Path("frames"), options_);
  EXPECT_EQ(result.yaw_reference, "true");
  EXPECT_NEAR(image_up_bearing(result), 10.0 + c, 1e-6);
  EXPECT_NEAR(result.max_convergence_deg, std::abs(c), 1e-6);
  options_.yaw_reference = "grid";
  result = ImportTelemetry(Path("frames"), options_);
  EXPECT_NEAR(image_up_bearing(result), 10.0, 1e-9);
  EXPECT_EQ(result.max_convergence_deg, 0.0);
  options_.yaw_reference = "magnetic";
  EXPECT_THAT(ErrorOf([&] { ImportTelemetry(Path("frames"), options_); }),
              HasSubstr("magnetic_declination_deg: yaw_reference 'magnetic' needs"));
  options_.magnetic_declination_deg = 4.0;
  result = ImportTelemetry(Path("frames"), options_);
  EXPECT_NEAR(image_up_bearing(result), 14.0 + c, 1e-6);
  EXPECT_EQ(result.declination_deg, 4.0);
  options_.yaw_reference = "true";
  EXPECT_THAT(ErrorOf([&] { ImportTelemetry(Path("frames"), options_); }),
              HasSubstr("magnetic_declination_deg: applies to yaw_reference 'magnetic' only"));
}

TEST_F(Telemetry, TakeoffAltitudesAddTheGivenOrSampledGroundHeight) {
  Frame("a.png");
  Frame("b.png");
  // a above (545000, 5318000), b 100 m north; altitudes 30 and 32 above the take-off point.
  const Vec3d a = TransformPoints({Vec3d(545000.0, 5318000.0, 0.0)}, "EPSG:32633", "EPSG:4326",
                                  "t")[0];
  const Vec3d b = TransformPoints({Vec3d(545000.0, 5318100.0, 0.0)}, "EPSG:32633", "EPSG:4326",
                                  "t")[0];
  char csv[512];
  std::snprintf(csv, sizeof(csv),
                "frame,lat,lon,alt,yaw,pitch,roll\na.png,%.10f,%.10f,30,0,-90,0\n"
                "b.png,%.10f,%.10f,32,0,-90,0\n",
                a.y, a.x, b.y, b.x);
  options_.telemetry_file = Write("log.csv", csv);
  options_.fov_deg = 60.0;
  options_.altitude_reference = "takeoff";
  EXPECT_THAT(ErrorOf([&] { ImportTelemetry(Path("frames"), options_); }),
              HasSubstr("takeoff_height_m: altitude_reference 'takeoff' needs the take-off "
                        "ground's height: give takeoff_height_m or dem"));
  options_.takeoff_height_m = 250.0;
  TelemetryResult result = ImportTelemetry(Path("frames"), options_);
  EXPECT_NEAR(result.light_field.views[1].cam_from_world.Center().z, 282.0, 1e-9);
  EXPECT_EQ(result.takeoff_height_from, "given");
  // A DEM in UTM 33N, the plane z = 300 + 0.01 (x - 544000) - 0.02 (y - 5317000), 10 m pixels:
  // bilinear sampling is exact on a plane. Under a: 300 + 10 - 20 = 290.
  Heightfield dem;
  dem.width = 300;
  dem.height = 300;
  dem.geotransform = {544000.0, 10.0, 0.0, 5320000.0, 0.0, -10.0};
  dem.crs_wkt = "EPSG:32633";
  for (int row = 0; row < dem.height; ++row) {
    for (int column = 0; column < dem.width; ++column) {
      dem.heights.push_back(static_cast<float>(300.0 + 0.01 * (dem.CenterX(column) - 544000.0) -
                                               0.02 * (dem.CenterY(row) - 5317000.0)));
    }
  }
  WriteHeightfield(Path("dem.tif"), dem);
  options_.takeoff_height_m.reset();
  options_.dem = Path("dem.tif");
  result = ImportTelemetry(Path("frames"), options_);
  EXPECT_NEAR(result.takeoff_height_m, 290.0, 1e-3);  // float32 heights
  EXPECT_NEAR(result.light_field.views[0].cam_from_world.Center().z, 320.0, 1e-3);
  EXPECT_THAT(result.takeoff_height_from, HasSubstr("dem.tif at the first frame a.png"));
  // A home point 100 m north (under b): 290 - 2 = 288.
  options_.home_latitude_deg = b.y;
  options_.home_longitude_deg = b.x;
  result = ImportTelemetry(Path("frames"), options_);
  EXPECT_NEAR(result.takeoff_height_m, 288.0, 1e-3);
  // Outside the raster: an error naming the DEM and the point.
  options_.home_latitude_deg = 47.0;
  EXPECT_THAT(ErrorOf([&] { ImportTelemetry(Path("frames"), options_); }),
              HasSubstr("dem.tif: dem: the home point (47, "));
  // A DEM without altitude_reference 'takeoff' is refused.
  options_.altitude_reference = "absolute";
  EXPECT_THAT(ErrorOf([&] { ImportTelemetry(Path("frames"), options_); }),
              HasSubstr("dem: applies to altitude_reference 'takeoff' only"));
}

TEST(OdmAngles, YawPitchRollInvertWorldFromCameraRotation) {
  for (const std::array<double, 3>& ypr : std::vector<std::array<double, 3>>{
           {10.0, -60.0, 2.0}, {-170.0, -85.0, -3.0}, {95.0, 0.0, 0.0}, {45.0, -90.0, 0.0}}) {
    for (const double bearing : {0.0, 0.02}) {
      const Mat3d cam_from_world =
          glm::transpose(WorldFromCameraRotation(ypr[0], ypr[1], ypr[2], bearing));
      const std::array<double, 3> back = YawPitchRollOfRotation(cam_from_world, bearing);
      for (int k = 0; k < 3; ++k) EXPECT_NEAR(back[k], ypr[k], 1e-9) << k;
    }
  }
  // Straight down, a roll is folded into the yaw: the same rotation.
  const Mat3d rolled = glm::transpose(WorldFromCameraRotation(30.0, -90.0, 5.0));
  const std::array<double, 3> folded = YawPitchRollOfRotation(rolled);
  EXPECT_EQ(folded[2], 0.0);
  EXPECT_LT(AngleBetweenDeg(glm::transpose(WorldFromCameraRotation(folded[0], folded[1], 0.0)),
                            rolled),
            1e-9);
}

TEST_F(Telemetry, OdmGeoTxtRoundTripsThePosesAndReadsEveryField) {
  // The CSV flight imported, written as geo.txt, and imported from it: the same poses.
  const std::vector<TruePose> truth = Flight();
  options_.telemetry_file = Write("log.csv", FlightCsv(truth));
  options_.fov_deg = 60.0;
  const LightField lf = ImportTelemetry(Path("frames"), options_).light_field;
  WriteOdmGeo(Path("geo.txt"), lf);
  EXPECT_THAT(ErrorOf([&] { WriteOdmGeo(Path("geo.txt"), lf); }), HasSubstr("geo.txt: exists"));
  const OdmGeoFile geo = ReadOdmGeo(Path("geo.txt"));
  EXPECT_EQ(geo.crs, "EPSG:32633");
  ASSERT_EQ(geo.entries.size(), truth.size());
  EXPECT_EQ(geo.entries[3].image, "f03.png");
  // ODM's convention: pitch 0 = nadir (f00 is a nadir view, gimbal pitch -90).
  EXPECT_NEAR((*geo.entries[0].yaw_pitch_roll_deg)[1], 0.0, 1e-9);
  options_.telemetry_file = Path("geo.txt");
  const TelemetryResult result = ImportTelemetry(Path("frames"), options_);
  EXPECT_EQ(result.source, "odm");
  const LightField& back = result.light_field;
  ASSERT_EQ(back.views.size(), lf.views.size());
  for (size_t i = 0; i < lf.views.size(); ++i) {
    SCOPED_TRACE(lf.views[i].name);
    EXPECT_EQ(back.views[i].name, lf.views[i].name);
    const Vec3d a = lf.views[i].cam_from_world.Center() + lf.origin;
    const Vec3d b = back.views[i].cam_from_world.Center() + back.origin;
    // geo.txt holds the centres exactly (shortest round-trip decimals); the import takes them to
    // WGS84 and back to UTM through PROJ, which returns them within 5e-6 m here (45 km off the
    // central meridian): 1e-5 m.
    EXPECT_NEAR(glm::length(a - b), 0.0, 1e-5);
    EXPECT_LT(AngleBetweenDeg(lf.views[i].cam_from_world.rotation,
                              back.views[i].cam_from_world.rotation),
              1e-6);
  }
  // ODM's own spellings: "WGS84 UTM 33N", tabs, accuracies and a label; comments skipped.
  const std::string path = Write("odm.txt",
                                 "# from ODM\nWGS84 UTM 33N\n"
                                 "a.JPG\t545000 5318000 100 10 -90 0 0.02 0.03 gcp-ish label\n"
                                 "b.JPG 545010 5318000\n");
  const OdmGeoFile odm = ReadOdmGeo(path);
  EXPECT_EQ(odm.crs, "EPSG:32633");
  ASSERT_EQ(odm.entries.size(), 2u);
  EXPECT_EQ(odm.entries[0].line, 3);
  EXPECT_EQ(odm.entries[0].position, Vec3d(545000.0, 5318000.0, 100.0));
  EXPECT_EQ((*odm.entries[0].yaw_pitch_roll_deg)[0], 10.0);
  EXPECT_EQ((*odm.entries[0].accuracy_m)[1], 0.03);
  EXPECT_EQ(odm.entries[0].extras, "gcp-ish label");
  EXPECT_FALSE(odm.entries[1].has_z);
  EXPECT_FALSE(odm.entries[1].yaw_pitch_roll_deg.has_value());
  // Bad input: one error naming the file, the line and the field.
  EXPECT_THAT(ErrorOf([&] { ReadOdmGeo(Write("bad1.txt", "EPSG:999999\na.JPG 1 2 3\n")); }),
              HasSubstr("bad1.txt: line 1: projection"));
  EXPECT_THAT(ErrorOf([&] { ReadOdmGeo(Write("bad2.txt", "EPSG:32633\na.JPG 1 2 3 4\n")); }),
              HasSubstr("bad2.txt: line 2: camera angles: give yaw, pitch and roll together"));
  EXPECT_THAT(ErrorOf([&] {
                ReadOdmGeo(Write("bad3.txt", "EPSG:32633\na.JPG 1 2\na.JPG 3 4\n"));
              }),
              HasSubstr("bad3.txt: line 3: image_name: \"a.JPG\" is repeated"));
  EXPECT_THAT(ErrorOf([&] { ReadOdmGeo(Write("bad4.txt", "WGS84 UTM 61N\na.JPG 1 2\n")); }),
              HasSubstr("is not WGS84 UTM <zone 1..60><N|S>"));
  // Importing needs the heights and angles aos poses from.
  options_.telemetry_file = Write("flat.txt", "EPSG:32633\nf00.png 545000 5318000\n");
  EXPECT_THAT(ErrorOf([&] { ImportTelemetry(Path("frames"), options_); }),
              HasSubstr("flat.txt: line 2: geo_z: missing (image f00.png)"));
  options_.telemetry_file = Write("flat.txt", "EPSG:32633\nf00.png 545000 5318000 100\n");
  EXPECT_THAT(ErrorOf([&] { ImportTelemetry(Path("frames"), options_); }),
              HasSubstr("flat.txt: line 2: yaw pitch roll: missing (image f00.png)"));
  // ODM's placeholder 0 0 0 is a nadir camera with its image top at (true) north, and warned
  // about; on zone 33's central meridian that is NadirCamFromWorld.
  options_.telemetry_file = Write("zeros.txt", "EPSG:4326\nf00.png 15.0 48.0 100 0 0 0\n");
  const TelemetryResult zeros = ImportTelemetry(Path("frames"), options_);
  EXPECT_LT(AngleBetweenDeg(zeros.light_field.views[0].cam_from_world.rotation,
                            NadirCamFromWorld(Vec3d(0.0)).rotation),
            1e-6);
  ASSERT_FALSE(zeros.warnings.empty());
  EXPECT_THAT(zeros.warnings.front(), HasSubstr("every camera's yaw, pitch and roll are 0"));
  // Without a CRS there is nothing to write.
  LightField local = lf;
  local.crs.clear();
  EXPECT_THAT(ErrorOf([&] { WriteOdmGeo(Path("local.txt"), local); }),
              HasSubstr("local.txt: the light field has no CRS"));
}

}  // namespace
}  // namespace aos
