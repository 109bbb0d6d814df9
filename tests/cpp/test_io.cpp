#include <gtest/gtest.h>

#include <cstdio>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <stdexcept>

#include "probslam/core/angle.hpp"
#include "probslam/core/check.hpp"
#include "probslam/io/carmen_log.hpp"
#include "probslam/io/grid_file.hpp"
#include "probslam/io/ros_map.hpp"

using namespace probslam;
namespace fs = std::filesystem;

namespace {

fs::path scratch(const std::string& name) {
  const fs::path dir = fs::temp_directory_path() / ("probslam_test_" + std::to_string(::getpid()));
  fs::create_directories(dir);
  return dir / name;
}

std::string expect_invalid(const std::function<void()>& f) {
  try {
    f();
  } catch (const std::invalid_argument& e) {
    return e.what();
  }
  ADD_FAILURE() << "no std::invalid_argument thrown";
  return "";
}

}  // namespace

TEST(CarmenLog, ParsesMessagesAndAngles) {
  std::istringstream text(
      "# comment\n"
      "PARAM laser_front_laser_resolution 1.0 nohost 0\n"
      "ODOM 1 2 0.5 0.3 0.1 0 10.5 host 10.5\n"
      "FLASER 4 1.0 2.0 3.0 4.0 0.1 0.2 0.3 1.1 1.2 1.3 11.0 host 11.0\n"
      "NEFF 12\n"
      "ROBOTLASER1 0 -1.5 3.0 1.0 80.0 0.01 0 3 5.0 6.0 7.0 0 0.5 0.6 0.7 0.4 0.5 0.6 0 0 0 0 0 12.0 host 12.0\n");
  const CarmenLog log = parse_carmen_log(text, "t.log");
  ASSERT_EQ(log.scans.ranges.rows(), 2);
  ASSERT_EQ(log.scans.ranges.cols(), 4);
  EXPECT_EQ(log.scans.ranges(0, 3), 4.0);
  EXPECT_TRUE(std::isnan(log.scans.ranges(1, 3)));  // padding
  EXPECT_EQ(log.scans.num_beams[1], 3);
  EXPECT_NEAR(log.scans.start_angles[0], -2 * kPi / 180, 1e-12);  // 4 beams of 1 degree
  EXPECT_EQ(log.scans.start_angles[1], -1.5);
  EXPECT_EQ(log.scans.max_ranges[1], 80.0);
  EXPECT_EQ(log.scans.laser_poses(1, 2), 0.7);
  EXPECT_EQ(log.scans.robot_poses(0, 0), 1.1);
  EXPECT_EQ(log.scans.timestamps[0], 11.0);
  EXPECT_EQ(log.odometry.poses.rows(), 1);
  EXPECT_EQ(log.odometry.velocities(0, 1), 0.1);
  EXPECT_EQ(log.params.at("laser_front_laser_resolution"), "1.0");
}

TEST(CarmenLog, FlaserDefaultStepRule) {
  std::istringstream text("FLASER 181 " + [] { std::string s; for (int i = 0; i < 181; ++i) s += "1 "; return s; }() +
                          "0 0 0 0 0 0\n");
  const CarmenLog log = parse_carmen_log(text);
  EXPECT_NEAR(log.scans.start_angles[0], -kPi / 2, 1e-12);
  EXPECT_NEAR(log.scans.start_angles[0] + 180 * log.scans.angular_resolutions[0], kPi / 2, 1e-12);
}

// A real log is read even with a few bad lines: they are skipped, counted and named by line.
TEST(CarmenLog, MalformedLinesAreSkippedCountedAndNamed) {
  std::istringstream text(
      "PARAM laser_front_laser_resolution 1.0 nohost 0\n"               // 1
      "ODOM 1 2 0.5 0.3 0.1 0 10.5 host 10.5\n"                         // 2
      "FLASER 2 1.0 2.0 0 0 0 0 0 0 11.0 host 11.0\n"                   // 3
      "%$#@ garbage !!\n"                                               // 4: not a message
      "FLASER 2 1.0 x 0 0 0 0 0 0 12.0 host 12.0\n"                     // 5: non-numeric range
      "ODOM 1 2 0.5 0.3 0.1 0 oops host 13.0\n"                         // 6: bad timestamp
      "NEFF 12\n"                                                       // 7: ignored, not bad
      "PARAM lonely\n"                                                  // 8: no value
      "FLASER 2 3.0 4.0 0 0 0 0 0 0 14.0 host 14.0\n"                   // 9
      "FLASER 180 1.0 1.0 1.0 1.0");                                    // 10: cut off mid-write
  const CarmenLog log = parse_carmen_log(text, "t.log");
  ASSERT_EQ(log.scans.ranges.rows(), 2);
  EXPECT_EQ(log.scans.ranges(1, 0), 3.0);
  EXPECT_EQ(log.scans.timestamps[1], 14.0);
  EXPECT_EQ(log.odometry.poses.rows(), 1);  // the bad ODOM line left nothing behind
  EXPECT_EQ(log.odometry.timestamps.size(), 1);
  EXPECT_EQ(log.params.count("lonely"), 0u);
  EXPECT_EQ(log.skipped_rows, 5u);
  ASSERT_EQ(log.skipped_lines.size(), 5u);
  const long expected_lines[] = {4, 5, 6, 8, 10};
  for (std::size_t k = 0; k < 5; ++k) EXPECT_EQ(log.skipped_lines[k].line, expected_lines[k]) << k;
  EXPECT_NE(log.skipped_lines[0].reason.find("not a CARMEN message"), std::string::npos);
  EXPECT_NE(log.skipped_lines[1].reason.find("('x') is not a number"), std::string::npos);
  EXPECT_NE(log.skipped_lines[2].reason.find("('oops') is not a number"), std::string::npos);
  EXPECT_NE(log.skipped_lines[3].reason.find("PARAM has 2 fields"), std::string::npos);
  EXPECT_NE(log.skipped_lines[4].reason.find("FLASER has 6 fields, expected at least 188"), std::string::npos);
  EXPECT_EQ(log.skipped_lines[1].reason.find("t.log"), std::string::npos);  // the reason alone
}

TEST(CarmenLog, SkippedLinesAreAllCountedTheFirstListed) {
  std::string text = "FLASER 1 1.0 0 0 0 0 0 0\n";
  for (int k = 0; k < 30; ++k) text += "FLASER 3 1 2\n";  // lines 2..31
  std::istringstream in(text);
  const CarmenLog log = parse_carmen_log(in, "many.log");
  EXPECT_EQ(log.scans.ranges.rows(), 1);
  EXPECT_EQ(log.skipped_rows, 30u);
  ASSERT_EQ(log.skipped_lines.size(), kCarmenMaxReportedLines);
  EXPECT_EQ(log.skipped_lines.front().line, 2);
  EXPECT_EQ(log.skipped_lines.back().line, static_cast<long>(kCarmenMaxReportedLines) + 1);
}

TEST(CarmenLog, NoValidScanIsAnErrorNamingTheFirstBadLine) {
  std::istringstream garbage("\nthis is not\na CARMEN log 1 2 3\n%%%\n");
  const std::string what = expect_invalid([&] { parse_carmen_log(garbage, "g.log"); });
  EXPECT_NE(what.find("g.log: no laser scan"), std::string::npos) << what;
  EXPECT_NE(what.find("3 malformed lines skipped"), std::string::npos) << what;
  EXPECT_NE(what.find("g.log:2: 'this' is not a CARMEN message name"), std::string::npos) << what;
  std::istringstream bad_number("ODOM 0 0 0 0 0 0\nFLASER 2 1.0 x 0 0 0 0 0 0\n");
  EXPECT_NE(expect_invalid([&] { parse_carmen_log(bad_number, "f.log"); }).find("f.log:2:"), std::string::npos);
  std::istringstream short_line("\n\nFLASER 5 1 2 3\n");
  EXPECT_NE(expect_invalid([&] { parse_carmen_log(short_line, "g.log"); }).find("g.log:3:"), std::string::npos);
  std::istringstream bad_count("FLASER -3 1 2 3 4 5 6\n");
  EXPECT_NE(expect_invalid([&] { parse_carmen_log(bad_count, "h.log"); }).find("h.log:1:"), std::string::npos);
  std::istringstream odometry_only("ODOM 0 0 0 0 0 0\n");
  EXPECT_NE(expect_invalid([&] { parse_carmen_log(odometry_only, "o.log"); }).find("o.log: no laser scan"),
            std::string::npos);
  EXPECT_THROW(read_carmen_log("/nonexistent/file.log"), std::invalid_argument);
}

TEST(CarmenLog, RealIntelCorrectedLogWhenPresent) {
  // The corrected log is gzip-compressed; the C++ test reads the raw .clf instead.
  const fs::path path = fs::path(PROBSLAM_SHARED_DATA) / "laser_2d/intel/intel.clf";
  if (!fs::exists(path)) GTEST_SKIP() << "dataset not present: " << path;
  const CarmenLog log = read_carmen_log(path.string());
  EXPECT_EQ(log.scans.ranges.rows(), 13631);
  EXPECT_EQ(log.scans.ranges.cols(), 180);
  EXPECT_EQ(log.odometry.poses.rows(), 26915);
  EXPECT_EQ(log.skipped_rows, 0u);
  EXPECT_NEAR(log.scans.angular_resolutions[0], kPi / 180, 1e-15);
}

TEST(RosMap, RoundTripKeepsClassesAndGeometry) {
  OccupancyGrid2D g(0.05, 7, 5, {-1.25, 3.5});
  g.log_odds()(0, 0) = 3.0;    // occupied
  g.log_odds()(4, 6) = -3.0;   // free
  g.log_odds()(2, 3) = 0.2;    // unknown (p = 0.55)
  const fs::path yaml = scratch("map.yaml");
  save_ros_map(g, yaml.string());
  // map_server convention: row 0 of the image is the top of the map.
  std::ifstream pgm(scratch("map.pgm"), std::ios::binary);
  std::string magic, comment;
  int w, h, maxval;
  pgm >> magic;
  pgm.get();
  std::getline(pgm, comment);
  pgm >> w >> h >> maxval;
  pgm.get();
  std::vector<unsigned char> px(w * h);
  pgm.read(reinterpret_cast<char*>(px.data()), w * h);
  EXPECT_EQ(magic, "P5");
  EXPECT_EQ(px[6 + 0 * w], 254);  // (row 4, col 6) free, at the top
  EXPECT_EQ(px[0 + 4 * w], 0);    // (row 0, col 0) occupied, at the bottom
  EXPECT_EQ(px[3 + 2 * w], 205);
  const OccupancyGrid2D back = load_ros_map(yaml.string());
  EXPECT_TRUE(back.same_geometry(g));
  EXPECT_GT(back.probability()(0, 0), 0.65);
  EXPECT_LT(back.probability()(4, 6), 0.196);
  EXPECT_EQ(back.log_odds()(2, 3), 0.0);
}

TEST(RosMap, MalformedYamlNamesTheLine) {
  const fs::path yaml = scratch("bad.yaml");
  std::ofstream(yaml) << "image: x.pgm\nresolution: abc\norigin: [0, 0, 0]\noccupied_thresh: 0.65\nfree_thresh: 0.2\n";
  EXPECT_NE(expect_invalid([&] { load_ros_map(yaml.string()); }).find("bad.yaml:2"), std::string::npos);
  std::ofstream(yaml) << "image: x.pgm\nresolution: 0.1\norigin: [0, 0]\noccupied_thresh: 0.65\nfree_thresh: 0.2\n";
  EXPECT_NE(expect_invalid([&] { load_ros_map(yaml.string()); }).find("bad.yaml:3"), std::string::npos);
}

// A missing file named by the caller is FileNotFound (an std::invalid_argument, for handlers of
// that); a missing file named inside a file being read makes that file invalid instead.
TEST(Readers, MissingFileIsFileNotFoundMissingReferenceIsInvalid) {
  const std::string missing = (scratch("none") / "nothing.here").string();
  EXPECT_THROW(read_carmen_log(missing), FileNotFound);
  EXPECT_THROW(load_ros_map(missing), FileNotFound);
  EXPECT_THROW(load_grid(missing), FileNotFound);
  const fs::path yaml = scratch("no_image.yaml");
  std::ofstream(yaml) << "image: absent.pgm\nresolution: 0.1\norigin: [0, 0, 0]\noccupied_thresh: 0.65\nfree_thresh: 0.2\n";
  try {
    load_ros_map(yaml.string());
    ADD_FAILURE() << "no exception";
  } catch (const FileNotFound&) {
    ADD_FAILURE() << "the yaml exists: a missing image is a bad yaml, not FileNotFound";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("absent.pgm"), std::string::npos) << e.what();
  }
}

TEST(GridFile, LosslessRoundTripAndCorruptFiles) {
  OccupancyGrid2D g(0.07, 9, 4, {0.3, -0.2}, 0.42, LogOddsClamp::none());
  g.set_beam_model({0.8, 0.35});
  for (int i = 0; i < 36; ++i) g.data()[i] = std::sin(i * 1.7) * 3;
  const fs::path path = scratch("g.psgrid");
  save_grid(g, path.string());
  const OccupancyGrid2D back = load_grid(path.string());
  EXPECT_TRUE(back.same_geometry(g));
  EXPECT_EQ(back.p_prior(), 0.42);
  EXPECT_FALSE(back.clamp().enabled);
  EXPECT_EQ(back.beam_model().p_hit, 0.8);
  EXPECT_EQ((Eigen::MatrixXd(back.log_odds()) - Eigen::MatrixXd(g.log_odds())).norm(), 0.0);
  fs::resize_file(path, fs::file_size(path) - 8);
  EXPECT_THROW(load_grid(path.string()), std::invalid_argument);
  std::ofstream(scratch("junk.psgrid")) << "not a grid";
  EXPECT_THROW(load_grid(scratch("junk.psgrid").string()), std::invalid_argument);
}
