// The 3-D pose graph readers and writer (g2o SE3, iSAM / GTSAM EDGE3, TORO 3-D).
#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <functional>
#include <map>
#include <sstream>
#include <stdexcept>

#include "probslam/io/pose_graph_file.hpp"
#include "probslam/io/pose_graph_file_3d.hpp"
#include "probslam/io/pose_graph_3d_graph.hpp"
#include "test_support.hpp"

using namespace probslam;
using probslam::test_support::expect_invalid;
namespace fs = std::filesystem;

namespace {

// Values parsed from decimal text and composed with a few products: double rounding only.
constexpr double kRoundingTolerance = 1e-12;

PoseGraph3DRead parse(const std::string& text, PoseGraphReadOptions options = {}) {
  std::istringstream in(text);
  return parse_pose_graph_3d(in, options);
}

PoseGraphReadOptions skipping() {
  PoseGraphReadOptions o;
  o.rows = RowPolicy::kSkipAndCount;
  return o;
}

// Rz(yaw) Ry(pitch) Rx(roll), written out element by element (the textbook ZYX matrix), as an
// independent reference for the reader's Euler angles.
Eigen::Matrix3d zyx(double roll, double pitch, double yaw) {
  const double cr = std::cos(roll), sr = std::sin(roll), cp = std::cos(pitch), sp = std::sin(pitch),
               cy = std::cos(yaw), sy = std::sin(yaw);
  Eigen::Matrix3d r;
  r << cy * cp, cy * sp * sr - sy * cr, cy * sp * cr + sy * sr,  //
      sy * cp, sy * sp * sr + cy * cr, sy * sp * cr - cy * sr,   //
      -sp, cp * sr, cp * cr;
  return r;
}

Eigen::Matrix4d homogeneous(const Eigen::Matrix3d& r, const Eigen::Vector3d& t) {
  Eigen::Matrix4d m = Eigen::Matrix4d::Identity();
  m.topLeftCorner<3, 3>() = r;
  m.topRightCorner<3, 1>() = t;
  return m;
}

// 21 upper-triangle entries 1..21 (row-major) on a dominant diagonal: positive definite, and
// each entry's place in the matrix tells where the reader put it.
std::string numbered_information() {
  std::ostringstream s;
  int k = 1;
  for (int i = 0; i < 6; ++i)
    for (int j = i; j < 6; ++j, ++k) s << ' ' << (i == j ? 1000 + k : k);
  return s.str();
}

const std::string kIdentityInformation = " 1 0 0 0 0 0 1 0 0 0 0 1 0 0 0 1 0 0 1 0 1";

fs::path shared(const std::string& relative) { return fs::path(PROBSLAM_SHARED_DATA) / "pose_graphs" / relative; }

}  // namespace

TEST(PoseGraphFile3D, ReadsG2oRecords) {
  const PoseGraph3DRead read = parse(
      "# a comment\n"
      "VERTEX_SE3:QUAT 0 0 0 0 0 0 0 1\n"
      "VERTEX_SE3:QUAT 7 1.5 -2 3.25 0 0 0.6 0.8\n"
      "FIX 0\n"
      "EDGE_SE3:QUAT 0 7 1 2 3 0.6 0 0 0.8" + numbered_information() + "\n");
  const PoseGraph3DData& g = read.graph;
  ASSERT_EQ(g.vertices.size(), 2u);
  ASSERT_EQ(g.edges.size(), 1u);
  EXPECT_EQ(read.report.rows, 4u);
  EXPECT_TRUE(g.vertices[0].fixed);
  EXPECT_FALSE(g.vertices[1].fixed);
  EXPECT_EQ(g.vertices[1].id, 7);
  EXPECT_EQ(g.vertices[1].t, Eigen::Vector3d(1.5, -2, 3.25));
  // qx qy qz qw in the file; Eigen's (w, x, y, z) constructor
  EXPECT_EQ(g.vertices[1].q.coeffs(), Eigen::Quaterniond(0.8, 0, 0, 0.6).coeffs());
  const Edge3D& e = g.edges[0];
  EXPECT_EQ(e.from_id, 0);
  EXPECT_EQ(e.to_id, 7);
  EXPECT_EQ(e.q.coeffs(), Eigen::Quaterniond(0.8, 0.6, 0, 0).coeffs());
  int k = 1;
  for (int i = 0; i < 6; ++i)
    for (int j = i; j < 6; ++j, ++k) {
      EXPECT_EQ(e.information(i, j), i == j ? 1000 + k : k) << i << "," << j;
      EXPECT_EQ(e.information(j, i), e.information(i, j));
    }
}

TEST(PoseGraphFile3D, IsamEulerAnglesAndSquareRootInformation) {
  const double roll = 0.3, pitch = -0.2, yaw = 2.5;
  std::ostringstream text;
  text.precision(17);
  text << "EDGE3 1 2 1 2 3 " << roll << ' ' << pitch << ' ' << yaw << numbered_information() << '\n';
  const PoseGraph3DRead read = parse(text.str());
  ASSERT_EQ(read.graph.edges.size(), 1u);
  const Edge3D& e = read.graph.edges[0];
  EXPECT_LT((e.q.toRotationMatrix() - zyx(roll, pitch, yaw)).cwiseAbs().maxCoeff(), kRoundingTolerance);
  // iSAM's entries are the upper-triangular square root R; the information is R^T R.
  Matrix6d r = Matrix6d::Zero();
  int k = 1;
  for (int i = 0; i < 6; ++i)
    for (int j = i; j < 6; ++j, ++k) r(i, j) = i == j ? 1000 + k : k;
  const Matrix6d expected = r.transpose() * r;
  EXPECT_LT((e.information - expected).cwiseAbs().maxCoeff(), kRoundingTolerance * expected.cwiseAbs().maxCoeff());
  // As GTSAM's load3D reads the same numbers: information.
  PoseGraphReadOptions information;
  information.noise = NoiseFormat::kInformation;
  const Matrix6d as_information = parse(text.str(), information).graph.edges[0].information;
  EXPECT_EQ(as_information, Matrix6d(r.selfadjointView<Eigen::Upper>()));
}

TEST(PoseGraphFile3D, ToroVertex3AndInformation) {
  const PoseGraph3DRead read = parse("VERTEX3 0 0 0 0 0 0 0\nVERTEX3 1 1 0 0 0.1 0.2 0.3\nEDGE3 0 1 1 0 0 0.1 0.2 0.3" +
                                     numbered_information() + "\n");
  ASSERT_EQ(read.graph.vertices.size(), 2u);
  EXPECT_LT((read.graph.vertices[1].q.toRotationMatrix() - zyx(0.1, 0.2, 0.3)).cwiseAbs().maxCoeff(),
            kRoundingTolerance);
  EXPECT_EQ(read.graph.edges[0].information(0, 1), 2.0);  // TORO: information, not its square root
}

TEST(PoseGraphFile3D, IsamFileIsDeadReckoned) {
  // 1 -> 2 -> 3, and 0 placed backwards from 1 (an edge 0 -> 1 naming its end first).
  const double a[3][6] = {{1, 0.5, -0.2, 0.1, -0.3, 0.7}, {0.3, -1, 2, -0.4, 0.2, 1.9}, {2, 1, 0, 0.5, 0.6, -2.8}};
  std::ostringstream text;
  text.precision(17);
  text << "EDGE3 1 2";
  for (double v : a[0]) text << ' ' << v;
  text << kIdentityInformation << "\nEDGE3 2 3";
  for (double v : a[1]) text << ' ' << v;
  text << kIdentityInformation << "\nEDGE3 0 1";
  for (double v : a[2]) text << ' ' << v;
  text << kIdentityInformation << '\n';
  const PoseGraph3DData g = parse(text.str()).graph;
  ASSERT_EQ(g.vertices.size(), 4u);
  auto z = [&](int k) { return homogeneous(zyx(a[k][3], a[k][4], a[k][5]), {a[k][0], a[k][1], a[k][2]}); };
  const Eigen::Matrix4d x1 = Eigen::Matrix4d::Identity(), x2 = x1 * z(0), x3 = x2 * z(1), x0 = x1 * z(2).inverse();
  const std::pair<int, Eigen::Matrix4d> expected[] = {{1, x1}, {2, x2}, {3, x3}, {0, x0}};
  for (std::size_t i = 0; i < 4; ++i) {
    const Vertex3D& v = g.vertices[i];
    EXPECT_EQ(v.id, expected[i].first);
    EXPECT_LT((homogeneous(v.q.toRotationMatrix(), v.t) - expected[i].second).cwiseAbs().maxCoeff(),
              kRoundingTolerance * 10);
  }
  const std::string what =
      expect_invalid([&] { parse(text.str() + "EDGE3 8 9 0 0 0 0 0 0" + kIdentityInformation + "\n"); });
  EXPECT_NE(what.find("<stream>:4: dead reckoning: vertices 8 and 9 are not connected"), std::string::npos) << what;
}

TEST(PoseGraphFile3D, QuaternionNearUnitIsNormalisedOthersRefused) {
  // Six printed digits: off unit by up to ~1e-6.
  const PoseGraph3DData g = parse("VERTEX_SE3:QUAT 0 0 0 0 0.190253 0.283162 -0.392318 0.854231\n").graph;
  EXPECT_NEAR(g.vertices[0].q.norm(), 1.0, kRoundingTolerance);
  EXPECT_NEAR(g.vertices[0].q.x(), 0.190253, 1e-6);
  std::string what = expect_invalid([] { parse("VERTEX_SE3:QUAT 0 0 0 0 0 0 0 1.001\n"); });
  EXPECT_NE(what.find("<stream>:1: quaternion (qx qy qz qw) has norm 1.001, not 1"), std::string::npos) << what;
  what = expect_invalid([] { parse("VERTEX_SE3:QUAT 0 0 0 0 0 0 0 0\n"); });
  EXPECT_NE(what.find("has norm 0"), std::string::npos) << what;
  what = expect_invalid([] { parse("VERTEX_SE3:QUAT 0 0 0 0 nan 0 0 1\n"); });
  EXPECT_NE(what.find("<stream>:1: quaternion must be finite"), std::string::npos) << what;
  what = expect_invalid([] { parse("VERTEX_SE3:QUAT 0 inf 0 0 0 0 0 1\n"); });
  EXPECT_NE(what.find("translation must be finite"), std::string::npos) << what;
}

TEST(PoseGraphFile3D, MalformedRecordsNameTheirLine) {
  const std::string v = "VERTEX_SE3:QUAT 0 0 0 0 0 0 0 1\nVERTEX_SE3:QUAT 1 1 0 0 0 0 0 1\n";
  const std::pair<std::string, std::string> cases[] = {
      {"EDGE_SE3:QUAT 0 1 1 0 0 0 0 0 1 1 0 0\n", "<stream>:3: EDGE_SE3:QUAT has 13 fields, expected at least 31"},
      {"EDGE_SE3:QUAT 0 1 x 0 0 0 0 0 1" + kIdentityInformation + "\n", "<stream>:3: field 4 ('x') is not a number"},
      {"EDGE_SE3:QUAT 0 500 1 0 0 0 0 0 1" + kIdentityInformation + "\n", "<stream>:3: unknown vertex 500"},
      {"EDGE_SE3:QUAT 1 1 1 0 0 0 0 0 1" + kIdentityInformation + "\n", "<stream>:3: edge from vertex 1 to itself"},
      {"EDGE_SE3:QUAT 0 1 1 0 0 0 0 0 1 -1 0 0 0 0 0 -1 0 0 0 0 -1 0 0 0 -1 0 0 -1 0 -1\n",
       "<stream>:3: information is not positive definite"},
      {"VERTEX_SE3:QUAT 1 1 0 0 0 0 0 1\n", "<stream>:3: vertex 1 given twice"},
      {"FIX 400\n", "<stream>:3: FIX names unknown vertex 400"},
      {"VERTEX_SE3:EXPMAP 2 0 0 0 0 0 0\n", "<stream>:3: unsupported g2o 3-D record 'VERTEX_SE3:EXPMAP'"},
      {"PARAMS_SE3OFFSET 0 1 0 0 0 0 0 1\nEDGE_SE3_PRIOR 0 0 0 0 0 0 0 0 1" + kIdentityInformation + "\n",
       "<stream>:4: EDGE_SE3_PRIOR through PARAMS_SE3OFFSET 0 (line 3), which is not the identity"},
      {"EDGE_SE3_PRIOR 0 3 0 0 0 0 0 0 1" + kIdentityInformation + "\n",
       "<stream>:3: EDGE_SE3_PRIOR names parameter 3, which no PARAMS_SE3OFFSET defines"},
  };
  for (const auto& [line, message] : cases) {
    const std::string what = expect_invalid([&] { parse(v + line); });
    EXPECT_NE(what.find(message), std::string::npos) << what;
    // The same line skipped and reported (one bad line in three is above kMaxBadRowFraction:
    // pad the file so that one is within it).
    std::string padded = v + line;
    for (int i = 2; i < 200; ++i) padded += "VERTEX_SE3:QUAT " + std::to_string(i) + " 0 0 0 0 0 0 1\n";
    const PoseGraph3DRead read = parse(padded, skipping());
    ASSERT_EQ(read.report.skipped_rows, 1u) << line;
    EXPECT_EQ(read.report.skipped_lines[0].line, line.rfind('\n', line.size() - 2) == std::string::npos ? 3 : 4);
  }
}

TEST(PoseGraphFile3D, IsamRecordsAreNamedAsIsam) {
  const std::string edge = "EDGE3 0 1 0 0 0 0 0 0" + kIdentityInformation + "\n";
  std::string what = expect_invalid([&] { parse(edge + "POINT3 0 1 2 3\n"); });
  EXPECT_NE(what.find("<stream>:2: unsupported 3-D iSAM record 'POINT3' (VERTEX3 and EDGE3 only)"), std::string::npos)
      << what;
  what = expect_invalid([&] { parse(edge + "EDGE3 1 2 0 0 0 0 0 0 1\n"); });
  EXPECT_NE(what.find("<stream>:2: EDGE3 has 10 fields, expected at least 30"), std::string::npos) << what;
  what = expect_invalid([&] { parse("VERTEX3 0 0 0 0 0 0 0\nPOINT3 0 1 2 3\n"); });
  EXPECT_NE(what.find("<stream>:2: unsupported 3-D TORO record 'POINT3'"), std::string::npos) << what;
}

TEST(PoseGraphFile3D, PriorIsKeptAsAPrior) {
  const PoseGraph3DData g = parse("VERTEX_SE3:QUAT 4 0 0 0 0 0 0 1\nPARAMS_SE3OFFSET 0 0 0 0 0 0 0 1\n"
                                  "EDGE_SE3_PRIOR 4 0 1 2 3 0 0 0 1" + numbered_information() + "\n")
                                .graph;
  ASSERT_EQ(g.priors.size(), 1u);
  EXPECT_EQ(g.priors[0].id, 4);
  EXPECT_EQ(g.priors[0].t, Eigen::Vector3d(1, 2, 3));
  EXPECT_EQ(g.priors[0].information(1, 2), 8.0);
  EXPECT_FALSE(g.vertices[0].fixed);
}

TEST(PoseGraphFile3D, TruncatedLastLineIsReportedByLine) {
  std::string text = "VERTEX_SE3:QUAT 0 0 0 0 0 0 0 1\n";
  for (int i = 1; i <= 150; ++i) text += "VERTEX_SE3:QUAT " + std::to_string(i) + " " + std::to_string(i) + " 0 0 0 0 0 1\n";
  for (int i = 0; i < 150; ++i)
    text += "EDGE_SE3:QUAT " + std::to_string(i) + " " + std::to_string(i + 1) + " 1 0 0 0 0 0 1" +
            kIdentityInformation + "\n";
  text += "EDGE_SE3:QUAT 150 0 1 0 0 0 0 0 1 1 0 0 0";  // cut while being written: no newline
  const std::string what = expect_invalid([&] { parse(text); });
  EXPECT_NE(what.find("<stream>:302: EDGE_SE3:QUAT has 14 fields, expected at least 31"), std::string::npos) << what;
  const PoseGraph3DRead read = parse(text, skipping());
  EXPECT_EQ(read.graph.edges.size(), 150u);
  ASSERT_EQ(read.report.skipped_rows, 1u);
  EXPECT_EQ(read.report.skipped_lines[0].line, 302);
  // Too many bad lines: fatal, naming the first.
  const std::string many = expect_invalid([&] { parse(text + "\nFIX\nFIX\nFIX\nFIX\n", skipping()); });
  EXPECT_NE(many.find("<stream>:302:"), std::string::npos) << many;
  EXPECT_NE(many.find("more than kMaxBadRowFraction"), std::string::npos) << many;
}

TEST(PoseGraphFile3D, WrongDimensionIsNamed) {
  std::istringstream in("VERTEX_SE3:QUAT 0 0 0 0 0 0 0 1\n");
  std::string what = expect_invalid([&] { parse_pose_graph(in, PoseGraphFormat::kAuto, "g.g2o"); });
  EXPECT_NE(what.find("g.g2o:1: this is a 3-D graph (VERTEX_SE3:QUAT): use read_pose_graph_3d"), std::string::npos)
      << what;
  std::istringstream isam("EDGE3 0 1 0 0 0 0 0 0" + kIdentityInformation + "\n");
  PoseGraphReadOptions options;
  options.rows = RowPolicy::kSkipAndCount;  // fatal under both policies
  what = expect_invalid([&] { parse_pose_graph(isam, options, "s.txt"); });
  EXPECT_NE(what.find("s.txt:1: this is a 3-D graph (EDGE3)"), std::string::npos) << what;
  what = expect_invalid([] { parse("VERTEX_SE2 0 0 0 0\n", skipping()); });
  EXPECT_NE(what.find("<stream>:1: this is a 2-D graph (VERTEX_SE2): use read_pose_graph"), std::string::npos) << what;
}

TEST(PoseGraphFile3D, G2oRoundTripIsExact) {
  PoseGraph3DData g;
  for (int i = 0; i < 5; ++i) {
    Vertex3D v;
    v.id = 10 * i + 3;
    v.q = Eigen::Quaterniond(Eigen::AngleAxisd(0.7 * i + 0.1, Eigen::Vector3d(1, -2, 0.5 * i).normalized()));
    v.t = Eigen::Vector3d(std::sqrt(2.0) * i, -1.0 / 3.0, 1e-9 * i);
    v.fixed = i == 2;
    g.vertices.push_back(v);
  }
  for (int i = 0; i < 4; ++i) {
    Edge3D e;
    e.from_id = g.vertices[i].id;
    e.to_id = g.vertices[i + 1].id;
    e.q = g.vertices[i].q.conjugate() * g.vertices[i + 1].q;
    e.t = Eigen::Vector3d(0.1 * i, M_PI, -std::exp(1.0));
    Matrix6d a = Matrix6d::Random();
    e.information = a * a.transpose() + Matrix6d::Identity();
    g.edges.push_back(e);
  }
  Prior3D p;
  p.id = 3;
  p.q = g.vertices[0].q;
  p.information = 1e6 * Matrix6d::Identity();
  g.priors.push_back(p);
  std::ostringstream out;
  write_g2o_3d(out, g);
  const PoseGraph3DData back = parse(out.str()).graph;
  ASSERT_EQ(back.vertices.size(), g.vertices.size());
  for (std::size_t i = 0; i < g.vertices.size(); ++i) {
    EXPECT_EQ(back.vertices[i].id, g.vertices[i].id);
    EXPECT_EQ(back.vertices[i].q.coeffs(), g.vertices[i].q.coeffs());
    EXPECT_EQ(back.vertices[i].t, g.vertices[i].t);
    EXPECT_EQ(back.vertices[i].fixed, g.vertices[i].fixed);
  }
  ASSERT_EQ(back.edges.size(), g.edges.size());
  for (std::size_t i = 0; i < g.edges.size(); ++i) {
    EXPECT_EQ(back.edges[i].q.coeffs(), g.edges[i].q.coeffs());
    EXPECT_EQ(back.edges[i].t, g.edges[i].t);
    EXPECT_EQ(back.edges[i].information, Matrix6d(g.edges[i].information.selfadjointView<Eigen::Upper>()));
  }
  ASSERT_EQ(back.priors.size(), 1u);
  EXPECT_EQ(back.priors[0].information, p.information);
  std::ostringstream again;
  write_g2o_3d(again, back);
  EXPECT_EQ(again.str(), out.str());
  g.edges[0].to_id = 99;
  std::ostringstream refused;
  const std::string what = expect_invalid([&] { write_g2o_3d(refused, g); });
  EXPECT_NE(what.find("unknown vertex 99"), std::string::npos) << what;
  EXPECT_TRUE(refused.str().empty());
}

TEST(PoseGraphFile3D, FileToGraphAndBack) {
  // A file's records become the graph's vertices (FIX kept), edges and priors, and the graph
  // written and read again is the same graph: values to the rounding of one normalisation.
  constexpr double kNormalisationTolerance = 1e-15;
  const std::string text =
      "VERTEX_SE3:QUAT 7 1 2 3 0 0 0.6 0.8\nVERTEX_SE3:QUAT 9 -1 0.5 2 0.5 0.5 0.5 0.5\nFIX 9\n"
      "EDGE_SE3:QUAT 7 9 0.25 0 -1 0 0.6 0 0.8" + numbered_information() + "\n"
      "PARAMS_SE3OFFSET 0 0 0 0 0 0 0 1\nEDGE_SE3_PRIOR 7 0 1 2 3.5 0 0 0.6 0.8" + kIdentityInformation + "\n";
  const PoseGraph3DData data = parse(text).graph;
  const PoseGraph3D g = pose_graph_3d_from_data(data);
  ASSERT_EQ(g.num_vertices(), 2);
  EXPECT_FALSE(g.vertex(g.index_of(7)).fixed);
  EXPECT_TRUE(g.vertex(g.index_of(9)).fixed);
  ASSERT_EQ(g.pose_edges().size(), 1u);
  EXPECT_EQ(g.pose_edges()[0].information, data.edges[0].information);
  ASSERT_EQ(g.pose_priors().size(), 1u);
  EXPECT_EQ(g.vertex(g.pose_priors()[0].vertex).id, 7);
  // The prior holds pose 7 0.5 m above its value (same rotation, about z), unit information:
  // chi2 0.25.
  EXPECT_NEAR(g.prior_chi2()[0], 0.25, kRoundingTolerance);

  std::ostringstream out;
  write_g2o_3d(out, pose_graph_3d_data(g));
  const PoseGraph3D back = pose_graph_3d_from_data(parse(out.str()).graph);
  ASSERT_EQ(back.num_vertices(), g.num_vertices());
  for (int v = 0; v < g.num_vertices(); ++v) {
    EXPECT_EQ(back.vertex(v).id, g.vertex(v).id);
    EXPECT_EQ(back.vertex(v).fixed, g.vertex(v).fixed);
    EXPECT_LE((back.vertex(v).value.rotation.coeffs() - g.vertex(v).value.rotation.coeffs()).norm(),
              kNormalisationTolerance);
    EXPECT_EQ(back.vertex(v).value.translation, g.vertex(v).value.translation);
  }
  ASSERT_EQ(back.pose_edges().size(), 1u);
  EXPECT_EQ(back.pose_edges()[0].information, g.pose_edges()[0].information);
  ASSERT_EQ(back.pose_priors().size(), 1u);
  EXPECT_EQ(back.pose_priors()[0].measurement.translation, g.pose_priors()[0].measurement.translation);
  EXPECT_NEAR(back.chi2(), g.chi2(), kRoundingTolerance);

  PoseGraph3DData twice = data;
  twice.vertices.push_back(twice.vertices[0]);
  const std::string what = expect_invalid([&] { pose_graph_3d_from_data(twice); });
  EXPECT_NE(what.find("7"), std::string::npos) << what;
}

TEST(PoseGraphFile3D, ShippedGraphsHaveTheirReadmeCounts) {
  struct Case {
    const char* path;
    std::size_t vertices, edges;
  };
  // Counts from each folder's README.md (verified there with grep).
  const Case cases[] = {{"sphere2500/sphere2500.g2o", 2500, 4949},
                        {"parking_garage/parking-garage.g2o", 1661, 6275},
                        {"torus3d/torus3D.g2o", 5000, 9048},
                        {"gtsam_examples/pose3example.txt", 5, 6},
                        {"sphere2500/sphere2500.txt", 2500, 4949}};
  for (const Case& c : cases) {
    const fs::path path = shared(c.path);
    if (!fs::exists(path)) GTEST_SKIP() << "dataset not present: " << path;
    const PoseGraph3DRead read = read_pose_graph_3d(path.string());
    EXPECT_EQ(read.graph.vertices.size(), c.vertices) << c.path;
    EXPECT_EQ(read.graph.edges.size(), c.edges) << c.path;
    EXPECT_EQ(read.report.skipped_rows, 0u) << c.path;
  }
}

TEST(PoseGraphFile3D, SphereIsamAndG2oFilesHoldTheSameMeasurements) {
  // The two copies of sphere2500 (iSAM's EDGE3 with roll pitch yaw, the g2o conversion with
  // quaternions) print the same edges to 6 digits: the Euler convention read from one agrees
  // with the quaternions of the other.
  constexpr double kPrintedDigits = 2e-6;  // both files print 6 significant digits
  const fs::path txt = shared("sphere2500/sphere2500.txt"), g2o = shared("sphere2500/sphere2500.g2o");
  if (!fs::exists(txt) || !fs::exists(g2o)) GTEST_SKIP() << "dataset not present: " << txt;
  const PoseGraph3DData a = read_pose_graph_3d(txt.string()).graph, b = read_pose_graph_3d(g2o.string()).graph;
  ASSERT_EQ(a.edges.size(), b.edges.size());
  std::map<std::pair<int, int>, const Edge3D*> by_ends;  // the files list the edges in different orders
  for (const Edge3D& e : b.edges) by_ends[{e.from_id, e.to_id}] = &e;
  for (const Edge3D& e : a.edges) {
    const auto other = by_ends.find({e.from_id, e.to_id});
    ASSERT_NE(other, by_ends.end()) << e.from_id << " " << e.to_id;
    EXPECT_LT((e.t - other->second->t).cwiseAbs().maxCoeff(), kPrintedDigits) << e.from_id << " " << e.to_id;
    EXPECT_LT(e.q.angularDistance(other->second->q), kPrintedDigits * 4) << e.from_id << " " << e.to_id;
  }
}
