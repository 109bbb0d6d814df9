#include <gtest/gtest.h>

#include <cstdio>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <stdexcept>
#include <utility>

#include "probslam/core/angle.hpp"
#include "probslam/core/check.hpp"
#include "probslam/io/carmen_log.hpp"
#include "probslam/io/pose_graph_file.hpp"
#include "probslam/io/ros_map.hpp"
#include "test_support.hpp"

using namespace probslam;
using probslam::test_support::expect_invalid;
namespace fs = std::filesystem;

namespace {

fs::path scratch(const std::string& name) {
  const fs::path dir = fs::temp_directory_path() / ("probslam_test_" + std::to_string(::getpid()));
  fs::create_directories(dir);
  return dir / name;
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

TEST(CarmenLog, EveryRecordIsTimedByItsLoggerStamp) {
  // Issue 49: the ipc stamp (the sender's clock, here 1000 s ahead) was the scans' time, while
  // the corrected Radish logs carry the logger stamp; a slam run's poses and the corrected log
  // shared no clock. A RAWLASER1 record (no pose) and a short ROBOTLASER1 trailer included.
  std::istringstream text(
      "ODOM 1 2 0.5 0.3 0.1 0 1010.5 host 10.5\n"
      "FLASER 2 1.0 2.0 0.1 0.2 0.3 1.1 1.2 1.3 1011.25 host 11.25\n"
      "RAWLASER1 0 -1.5 3.0 1.0 80.0 0.01 0 2 5.0 6.0 0 1011.5 host 11.5\n"
      "ROBOTLASER1 0 -1.5 3.0 1.0 80.0 0.01 0 2 5.0 6.0 0 0.5 0.6 0.7 0.4 0.5 0.6 0 0 0 0 0 1012.0 host 12.0\n"
      "ROBOTLASER1 0 -1.5 3.0 1.0 80.0 0.01 0 2 5.0 6.0 0 0.5 0.6 0.7 0.4 0.5 0.6 1013.0 host 13.0\n"
      "FLASER 2 1.0 2.0 0.1 0.2 0.3 1.1 1.2 1.3 1014.0\n"  // no logger stamp: the ipc one
      "FLASER 2 1.0 2.0 0.1 0.2 0.3 1.1 1.2 1.3\n");       // no stamp at all
  const CarmenLog log = parse_carmen_log(text, "t.log");
  ASSERT_EQ(log.scans.timestamps.size(), 5);
  EXPECT_EQ(log.scans.timestamps[0], 11.25);
  EXPECT_EQ(log.scans.ipc_timestamps[0], 1011.25);
  EXPECT_EQ(log.scans.timestamps[1], 12.0);
  EXPECT_EQ(log.scans.ipc_timestamps[1], 1012.0);
  EXPECT_EQ(log.scans.timestamps[2], 13.0);  // older ROBOTLASER1: fewer fields, trailer read from the end
  EXPECT_EQ(log.scans.ipc_timestamps[2], 1013.0);
  EXPECT_EQ(log.scans.timestamps[3], 1014.0);
  EXPECT_TRUE(std::isnan(log.scans.timestamps[4]) && std::isnan(log.scans.ipc_timestamps[4]));
  ASSERT_EQ(log.odometry.timestamps.size(), 1);
  EXPECT_EQ(log.odometry.timestamps[0], 10.5);
  EXPECT_EQ(log.odometry.ipc_timestamps[0], 1010.5);
  EXPECT_EQ(log.skipped_rows, 0u);
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

TEST(CarmenLog, BinaryInputIsOneLineNamingWhatItIs) {
  // The first bytes of a gzip, a bzip2 and an xz file, and NULs: the readers said
  // "'<binary bytes>' is not a CARMEN message name" before.
  const std::pair<std::string, std::string> cases[] = {
      {std::string("\x1f\x8b\x08\x00\x00\x00\x00\x00\x02\x03uN\n", 13), "gzip-compressed data, not text"},
      {"BZh91AY&SY\x9a\xa1\n", "bzip2-compressed data, not text"},
      {std::string("\xfd" "7zXZ\0\0\x04\n", 9), "xz-compressed data, not text"},
      {std::string("FLASER \0\0\0\n", 11), "binary data (a NUL byte in the first line), not a text file"}};
  const auto compressed_tail = [](const std::string& said) {
    return said.find("compressed") != std::string::npos ? ": decompress it first (this reader takes plain text)" : "";
  };
  for (const auto& [bytes, said] : cases) {
    std::istringstream in(bytes + "FLASER 1 1.0 0 0 0 0 0 0\n");
    EXPECT_EQ(expect_invalid([&] { parse_carmen_log(in, "x.log"); }), "x.log: " + said + compressed_tail(said));
    std::istringstream graph(bytes + "VERTEX_SE2 0 0 0 0\n");
    EXPECT_EQ(expect_invalid([&] { parse_pose_graph(graph, PoseGraphFormat::kAuto, "x.g2o"); }),
              "x.g2o: " + said + compressed_tail(said));
  }
  // A NUL further on is a damaged line, skipped and counted as any other.
  std::istringstream damaged(std::string("FLASER 1 1.0 0 0 0 0 0 0\nFLASER ") + '\0' + "\n");
  EXPECT_EQ(parse_carmen_log(damaged, "d.log").skipped_rows, 1u);
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
  EXPECT_THROW(OccupancyGrid2D::load(missing), FileNotFound);
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

// --- pose graph files: the noise convention and the row policy --------------------------------

namespace {

// One noise by hand: R upper triangular, information Omega = R^T R, covariance C = Omega^-1
// (det Omega = det(R)^2 = 1600; C = adj(Omega) / 1600). 2-D: R2, Omega2, C2 (det 64).
//   R = [2 1 0; 0 4 2; 0 0 5]   Omega = [4 2 0; 2 17 8; 0 8 29]
//   C = [429 -58 16; -58 116 -32; 16 -32 64] / 1600
//   R2 = [2 1; 0 4]   Omega2 = [4 2; 2 17]   C2 = [17 -2; -2 4] / 64
const Eigen::Matrix3d kOmega = (Eigen::Matrix3d() << 4, 2, 0, 2, 17, 8, 0, 8, 29).finished();
const Eigen::Matrix2d kOmega2 = (Eigen::Matrix2d() << 4, 2, 2, 17).finished();
const char* kR = "2 1 0 4 2 5";
const char* kOmegaUpper = "4 2 0 17 8 29";
const char* kOmegaToro = "4 2 17 29 0 8";  // xx xy yy tt xt yt
const char* kC = "0.268125 -0.03625 0.01 0.0725 -0.02 0.04";
const char* kR2 = "2 1 4";
const char* kOmega2Upper = "4 2 17";
const char* kC2 = "0.265625 -0.03125 0.0625";

PoseGraphRead read_text(const std::string& text, PoseGraphFormat format, NoiseFormat noise,
                        RowPolicy rows = RowPolicy::kStrict) {
  std::istringstream in(text);
  PoseGraphReadOptions options;
  options.format = format;
  options.noise = noise;
  options.rows = rows;
  return parse_pose_graph(in, options, "g.txt");
}

void expect_information(const PoseGraph2D& g, const std::string& what) {
  ASSERT_EQ(g.pose_edges().size(), 1u) << what;
  EXPECT_LE((g.pose_edges()[0].information - kOmega).norm(), 1e-12 * kOmega.norm()) << what;
  if (g.point_edges().empty()) return;
  EXPECT_LE((g.point_edges()[0].information - kOmega2).norm(), 1e-12 * kOmega2.norm()) << what;
}

std::string odometry_lines(int n) {
  std::string text;
  for (int k = 0; k < n; ++k)
    text += "ODOMETRY " + std::to_string(k) + " " + std::to_string(k + 1) + " 1 0 0 10 0 0 10 0 31.6\n";
  return text;
}

}  // namespace

TEST(PoseGraphNoise, EveryNoiseFormatReadsTheSameInformation) {
  using F = PoseGraphFormat;
  using N = NoiseFormat;
  const std::string isam_edges[][2] = {{kR, kR2}, {kOmegaUpper, kOmega2Upper}, {kC, kC2}};
  const N isam_noise[] = {N::kSquareRootInformation, N::kInformation, N::kCovariance};
  for (int k = 0; k < 3; ++k) {
    const std::string text = "ODOMETRY 0 1 1 0 0 " + isam_edges[k][0] + "\nLANDMARK 1 7 2 1 " + isam_edges[k][1] + "\n";
    expect_information(read_text(text, F::kIsam, isam_noise[k]).graph, "isam " + std::to_string(k));
    if (k == 0) expect_information(read_text(text, F::kAuto, N::kDefault).graph, "isam default");
  }
  const std::string g2o_edges[][2] = {{kOmegaUpper, kOmega2Upper}, {kR, kR2}, {kC, kC2}};
  const N g2o_noise[] = {N::kInformation, N::kSquareRootInformation, N::kCovariance};
  for (int k = 0; k < 3; ++k) {
    const std::string text = "VERTEX_SE2 0 0 0 0\nVERTEX_SE2 1 1 0 0\nVERTEX_XY 7 3 1\nEDGE_SE2 0 1 1 0 0 " +
                             g2o_edges[k][0] + "\nEDGE_SE2_XY 1 7 2 1 " + g2o_edges[k][1] + "\n";
    expect_information(read_text(text, F::kG2o, g2o_noise[k]).graph, "g2o " + std::to_string(k));
    if (k == 0) expect_information(read_text(text, F::kAuto, N::kDefault).graph, "g2o default");
  }
  const std::string toro = "VERTEX2 0 0 0 0\nVERTEX2 1 1 0 0\nEDGE2 0 1 1 0 0 " + std::string(kOmegaToro) + "\n";
  expect_information(read_text(toro, F::kToro, N::kDefault).graph, "toro default");
  expect_information(read_text(toro, F::kToro, N::kInformation).graph, "toro information");
}

TEST(PoseGraphNoise, CovarianceThatIsNotPositiveDefiniteNamesTheLine) {
  const std::string what = expect_invalid([] {
    read_text("ODOMETRY 0 1 1 0 0 1 0 0 -1 0 1\n", PoseGraphFormat::kIsam, NoiseFormat::kCovariance);
  });
  EXPECT_NE(what.find("g.txt:1: covariance is not positive definite"), std::string::npos) << what;
}

TEST(PoseGraphRows, StrictIsTheDefaultAndNamesTheFirstBadLine) {
  const std::string text = odometry_lines(200) + "LANDMARK 3 7 2 x 1 0 1\n";
  const std::string what = expect_invalid([&] { read_text(text, PoseGraphFormat::kIsam, NoiseFormat::kDefault); });
  EXPECT_NE(what.find("g.txt:201: field 5 ('x') is not a number"), std::string::npos) << what;
  std::istringstream in(text);
  EXPECT_THROW(parse_pose_graph(in, PoseGraphFormat::kIsam, "g.txt"), std::invalid_argument);
}

TEST(PoseGraphRows, SkipAndCountSkipsCountsAndNamesBadRows) {
  const std::string good = odometry_lines(200) + "LANDMARK 3 7 2 1 1 0 1\nLANDMARK 3 7 2 1 0 0 0\n";
  const PoseGraphRead read = read_text(good, PoseGraphFormat::kIsam, NoiseFormat::kDefault, RowPolicy::kSkipAndCount);
  EXPECT_EQ(read.report.rows, 202u);
  EXPECT_EQ(read.report.skipped_rows, 1u);
  ASSERT_EQ(read.report.skipped_lines.size(), 1u);
  EXPECT_EQ(read.report.skipped_lines[0].line, 202);
  EXPECT_NE(read.report.skipped_lines[0].reason.find("information"), std::string::npos)
      << read.report.skipped_lines[0].reason;  // R zero: R^T R has no positive eigenvalue to keep
  EXPECT_EQ(read.graph.pose_edges().size(), 200u);
  EXPECT_EQ(read.graph.point_edges().size(), 1u);

  std::string mixed = odometry_lines(200);
  mixed += "LANDMARK 3 7 2\nBOGUS 1 2\n";  // 2 bad records of 202: within kMaxBadRowFraction (1 %)
  const PoseGraphRead two = read_text(mixed, PoseGraphFormat::kIsam, NoiseFormat::kDefault, RowPolicy::kSkipAndCount);
  EXPECT_EQ(two.report.rows, 202u);
  EXPECT_EQ(two.report.skipped_rows, 2u);
  ASSERT_EQ(two.report.skipped_lines.size(), 2u);
  EXPECT_EQ(two.report.skipped_lines[0].line, 201);
  EXPECT_NE(two.report.skipped_lines[0].reason.find("LANDMARK has 4 fields, expected at least 8 fields"),
            std::string::npos);
  EXPECT_EQ(two.report.skipped_lines[1].line, 202);
  EXPECT_NE(two.report.skipped_lines[1].reason.find("unsupported iSAM record 'BOGUS'"), std::string::npos);
  EXPECT_EQ(read_text(odometry_lines(3), PoseGraphFormat::kIsam, NoiseFormat::kDefault, RowPolicy::kSkipAndCount)
                .report.skipped_rows,
            0u);
}

TEST(PoseGraphRows, AllSkippedRowsAreCountedTheFirstListed) {
  std::string text = odometry_lines(3000);
  for (int k = 0; k < 25; ++k) text += "LANDMARK 5 " + std::to_string(k) + " 1\n";  // 25 of 3025: 0.8 %
  const PoseGraphRead read = read_text(text, PoseGraphFormat::kIsam, NoiseFormat::kDefault, RowPolicy::kSkipAndCount);
  EXPECT_EQ(read.report.skipped_rows, 25u);
  ASSERT_EQ(read.report.skipped_lines.size(), kPoseGraphMaxReportedLines);
  EXPECT_EQ(read.report.skipped_lines.front().line, 3001);
  EXPECT_EQ(read.report.skipped_lines.back().line, 3000 + static_cast<long>(kPoseGraphMaxReportedLines));
}

TEST(PoseGraphRows, BuildTimeErrorsAreRowLevelToo) {
  // g2o: an edge naming a vertex the file does not list, and a FIX of one, are skipped
  std::string text;
  for (int k = 0; k <= 150; ++k) text += "VERTEX_SE2 " + std::to_string(k) + " " + std::to_string(k) + " 0 0\n";
  for (int k = 0; k < 150; ++k)
    text += "EDGE_SE2 " + std::to_string(k) + " " + std::to_string(k + 1) + " 1 0 0 " + kOmegaUpper + "\n";
  text += "EDGE_SE2 3 999 1 0 0 " + std::string(kOmegaUpper) + "\nFIX 998\n";  // lines 302, 303
  const PoseGraphRead read = read_text(text, PoseGraphFormat::kG2o, NoiseFormat::kDefault, RowPolicy::kSkipAndCount);
  EXPECT_EQ(read.report.rows, 303u);
  ASSERT_EQ(read.report.skipped_rows, 2u);
  EXPECT_EQ(read.report.skipped_lines[0].line, 302);
  EXPECT_NE(read.report.skipped_lines[0].reason.find("999"), std::string::npos) << read.report.skipped_lines[0].reason;
  EXPECT_EQ(read.report.skipped_lines[1].line, 303);
  EXPECT_EQ(read.graph.pose_edges().size(), 150u);
  const std::string what = expect_invalid([&] { read_text(text, PoseGraphFormat::kG2o, NoiseFormat::kDefault); });
  EXPECT_NE(what.find("g.txt:302:"), std::string::npos) << what;
}

TEST(PoseGraphRows, MoreThanTheFractionIsFatalNamingTheFirstBadLine) {
  // 3 bad of 203 (1.5 %): the first bad line, and the counts, in the message
  const std::string text = odometry_lines(100) + "LANDMARK 3 7 2 x 1 0 1\n" +
                           odometry_lines(200).substr(odometry_lines(100).size()) + "BOGUS\nLANDMARK 1 9 1\n";
  const std::string what = expect_invalid(
      [&] { read_text(text, PoseGraphFormat::kIsam, NoiseFormat::kDefault, RowPolicy::kSkipAndCount); });
  EXPECT_NE(what.find("g.txt:101: field 5 ('x') is not a number"), std::string::npos) << what;
  EXPECT_NE(what.find("3 of 203 rows unreadable, more than kMaxBadRowFraction = 0.01"), std::string::npos) << what;
}

TEST(PoseGraphRows, AnOdometryGapLeavesTheRestUnreachable) {
  // dead reckoning cannot place pose 51 once 50 -> 51 is skipped: every later edge is skipped too
  std::string text = odometry_lines(200);
  const std::string cut = "ODOMETRY 50 51 1 0 0 10 0 0 10 0 31.6\n";
  text.replace(text.find(cut), cut.size(), "ODOMETRY 50 51 1\n");
  const std::string what = expect_invalid(
      [&] { read_text(text, PoseGraphFormat::kIsam, NoiseFormat::kDefault, RowPolicy::kSkipAndCount); });
  EXPECT_NE(what.find("g.txt:51:"), std::string::npos) << what;
  EXPECT_NE(what.find("150 of 200 rows unreadable"), std::string::npos) << what;
}
