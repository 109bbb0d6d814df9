#include "probslam/io/pose_graph_file.hpp"

#include <Eigen/Cholesky>
#include <algorithm>
#include <cmath>
#include <fstream>
#include <set>
#include <sstream>
#include <limits>
#include <optional>
#include <unordered_map>
#include <utility>
#include <vector>

#include "probslam/core/check.hpp"
#include "probslam/core/pose2.hpp"
#include "noise_information.hpp"
#include "pose_graph_row_log.hpp"
#include "text_fields.hpp"

namespace probslam {
namespace {

using io_detail::Fields;
using io_detail::LineError;
using io_detail::LineParseError;
using io_detail::information_from;
using io_detail::own_noise;
using io_detail::RowLog;

struct VertexRecord {
  long line;
  int id;
  VertexKind kind;
  Eigen::Vector3d value;
};

struct EdgeRecord {
  long line;
  bool to_point;  // EDGE_SE2_XY / LANDMARK
  int from, to;   // vertex ids (iSAM landmarks: after separate_landmark_ids)
  Eigen::Vector3d measurement;  // (dx, dy, dtheta) or (dx, dy, 0)
  Eigen::Matrix3d information;  // top-left 2x2 for point edges
  int landmark = 0;  // the file's own id of the point, for point edges
  bool skipped = false;  // dead reckoning could not place it (RowPolicy::kSkipAndCount)
};

struct Records {
  std::vector<VertexRecord> vertices;
  std::vector<EdgeRecord> edges;
  std::vector<std::pair<long, std::vector<int>>> fixed;  // line, ids of one FIX record
  std::vector<std::pair<long, std::pair<int, int>>> equivalences;  // line, ids of one TORO EQUIV
};

// Runs add() for the record of `line`: an error it raises names that line (after `context`).
template <class Add>
void at_line(const std::string& source, long line, const std::string& context, Add&& add) {
  try {
    add();
  } catch (const LineParseError&) {
    throw;  // already names its line
  } catch (const std::invalid_argument& e) {
    LineError(source, line).fail(context + e.what());
  }
}

Eigen::Matrix3d symmetric3(double a11, double a12, double a13, double a22, double a23, double a33) {
  Eigen::Matrix3d m;
  m << a11, a12, a13, a12, a22, a23, a13, a23, a33;
  return m;
}

Eigen::Matrix2d symmetric2(double a11, double a12, double a22) {
  Eigen::Matrix2d m;
  m << a11, a12, a12, a22;
  return m;
}

// The checks PoseGraph2D makes when the edge is added, made on the record so that a skip-and-
// count read can skip the line before dead reckoning uses it. The information is built
// symmetric, so no symmetry tolerance.
template <class Measurement, class Information>
void check_edge(const Measurement& z, const Information& information, const LineError& err) {
  try {
    require_all_finite(z, "measurement");
    require_symmetric_positive_definite(information, "information", 0.0);
  } catch (const std::invalid_argument& e) {
    err.fail(e.what());
  }
}

int vertex_id(const Fields& f, std::size_t i, const LineError& err) {
  const long id = f.integer(i);
  if (id < std::numeric_limits<int>::min() || id > std::numeric_limits<int>::max())
    err.fail("vertex id " + std::to_string(id) + " out of range");
  return static_cast<int>(id);
}

// Records of 3-D graphs (g2o SE3, iSAM / TORO 3-D): a 2-D reader given one says so and names the
// 3-D reader, rather than calling a well-formed file unsupported.
bool is_3d_tag(const std::string& tag) {
  static const std::set<std::string> tags = {"VERTEX_SE3:QUAT", "EDGE_SE3:QUAT", "EDGE_SE3_PRIOR", "PARAMS_SE3OFFSET",
                                             "VERTEX_TRACKXYZ", "EDGE_SE3_TRACKXYZ", "VERTEX3", "EDGE3"};
  return tags.count(tag) != 0;
}

PoseGraphFormat detect(const std::string& tag) {
  if (tag == "VERTEX2") return PoseGraphFormat::kToro;
  if (tag == "ODOMETRY" || tag == "LANDMARK" || tag == "EDGE2") return PoseGraphFormat::kIsam;
  return PoseGraphFormat::kG2o;
}

void parse_line(const Fields& f, const std::string& tag, PoseGraphFormat format, NoiseFormat noise, long line,
                const LineError& err, Records& out, RowLog& rows) {
  // noise: the entries as the file orders them, made a symmetric matrix
  auto pose_edge = [&](const Eigen::Matrix3d& noise_entries) {
    const int from = vertex_id(f, 1, err), to = vertex_id(f, 2, err);
    const Eigen::Vector3d z(f.number(3), f.number(4), f.number(5));
    const Eigen::Matrix3d information = rows.repair<3>(information_from<3>(noise_entries, noise, err), line);
    check_edge(z, information, err);
    out.edges.push_back({line, false, from, to, z, information});
  };
  auto point_edge = [&](const Eigen::Matrix2d& noise_entries) {
    const int pose = vertex_id(f, 1, err), point = vertex_id(f, 2, err);
    const Eigen::Vector2d z(f.number(3), f.number(4));
    const Eigen::Matrix2d information = rows.repair<2>(information_from<2>(noise_entries, noise, err), line);
    check_edge(z, information, err);
    Eigen::Matrix3d info = Eigen::Matrix3d::Identity();
    info.topLeftCorner<2, 2>() = information;
    out.edges.push_back({line, true, pose, point, {z[0], z[1], 0.0}, info, point});
  };
  if (format == PoseGraphFormat::kG2o) {
    if (tag == "VERTEX_SE2") {
      f.need(5, "id x y theta");
      out.vertices.push_back({line, vertex_id(f, 1, err), VertexKind::kPose,
                              {f.number(2), f.number(3), f.number(4)}});
    } else if (tag == "VERTEX_XY") {
      f.need(4, "id x y");
      out.vertices.push_back({line, vertex_id(f, 1, err), VertexKind::kPoint, {f.number(2), f.number(3), 0.0}});
    } else if (tag == "EDGE_SE2") {
      f.need(12, "i j dx dy dtheta and 6 noise entries");
      pose_edge(symmetric3(f.number(6), f.number(7), f.number(8), f.number(9), f.number(10), f.number(11)));
    } else if (tag == "EDGE_SE2_XY") {
      f.need(8, "i j dx dy and 3 noise entries");
      point_edge(symmetric2(f.number(5), f.number(6), f.number(7)));
    } else if (tag == "FIX") {
      f.need(2, "vertex ids");
      std::vector<int> ids;
      for (std::size_t i = 1; i < f.size(); ++i) ids.push_back(vertex_id(f, i, err));
      out.fixed.emplace_back(line, std::move(ids));
    } else {
      err.fail("unsupported g2o record '" + tag + "' (2-D SE2 / XY graphs only)");
    }
  } else if (format == PoseGraphFormat::kToro) {
    if (tag == "VERTEX2") {
      f.need(5, "id x y theta");
      out.vertices.push_back({line, vertex_id(f, 1, err), VertexKind::kPose,
                              {f.number(2), f.number(3), f.number(4)}});
    } else if (tag == "EDGE2") {
      f.need(12, "i j dx dy dtheta and 6 noise entries");
      // TORO order: xx xy yy tt xt yt.
      pose_edge(symmetric3(f.number(6), f.number(7), f.number(10), f.number(8), f.number(11), f.number(9)));
    } else if (tag == "EQUIV") {
      f.need(3, "i j");
      const int a = vertex_id(f, 1, err), b = vertex_id(f, 2, err);
      if (a == b) err.fail("EQUIV names vertex " + std::to_string(a) + " twice");
      out.equivalences.push_back({line, {a, b}});
    } else {
      err.fail("unsupported TORO record '" + tag + "' (VERTEX2, EDGE2 and EQUIV only)");
    }
  } else {
    if (tag == "ODOMETRY" || tag == "EDGE2") {
      f.need(12, "i j dx dy dtheta and 6 noise entries");
      pose_edge(symmetric3(f.number(6), f.number(7), f.number(8), f.number(9), f.number(10), f.number(11)));
    } else if (tag == "LANDMARK") {
      f.need(8, "i j dx dy and 3 noise entries");
      point_edge(symmetric2(f.number(5), f.number(6), f.number(7)));
    } else {
      err.fail("unsupported iSAM record '" + tag + "' (ODOMETRY, EDGE2, LANDMARK only)");
    }
  }
}

// One edge's missing end, composed from the end already placed.
void add_missing_end(const EdgeRecord& e, PoseGraph2D& graph, const LineError& err) {
  const bool has_from = graph.has_vertex(e.from), has_to = graph.has_vertex(e.to);
  if (!has_from && graph.num_vertices() == 0) graph.add_pose(e.from, Eigen::Vector3d::Zero());
  if (!graph.has_vertex(e.from)) {
    if (e.to_point || !has_to)
      err.fail("vertex " + std::to_string(e.from) + " is not connected to the earlier records");
    const Pose2 to = Pose2::from_vector(graph.vertex(graph.index_of(e.to)).value);
    const Pose2 z = Pose2::from_vector(e.measurement);
    graph.add_pose(e.from, to.compose(z.inverse()).vector());
    return;
  }
  if (has_to) return;
  const Pose2 from = Pose2::from_vector(graph.vertex(graph.index_of(e.from)).value);
  if (e.to_point)
    graph.add_point(e.to, from.transform_from(e.measurement.head<2>()), e.landmark);
  else
    graph.add_pose(e.to, from.compose(Pose2::from_vector(e.measurement)).vector());
}

// Vertices the file did not list, from the edges in order: the dead-reckoning guess. An edge
// that cannot be placed is skipped under kSkipAndCount (and later edges from its end with it).
void add_missing_vertices(Records& records, PoseGraph2D& graph, const std::string& source, RowLog& rows) {
  for (EdgeRecord& e : records.edges) {
    e.skipped = !rows.row([&] {
      at_line(source, e.line, "dead reckoning: ", [&] { add_missing_end(e, graph, LineError(source, e.line)); });
    });
  }
}

// iSAM's loader keeps poses and landmarks in two tables, so a LANDMARK may reuse a pose's number.
// The graph has one id space (g2o's): when the two sets of numbers meet, every landmark is moved
// past the largest pose id (keeping their order); the file's number stays the point's
// landmark_id, which write_isam writes back.
void separate_landmark_ids(Records& records, const std::string& source) {
  std::set<long> poses, landmarks;
  for (const EdgeRecord& e : records.edges) {
    poses.insert(e.from);
    (e.to_point ? landmarks : poses).insert(e.to);
  }
  bool collide = false;
  for (const long l : landmarks) collide = collide || poses.count(l) != 0;
  if (!collide) return;
  const long offset = *poses.rbegin() + 1 - *landmarks.begin();
  if (*landmarks.rbegin() + offset > std::numeric_limits<int>::max())
    throw std::invalid_argument(source + ": landmark ids reuse pose ids and cannot be moved past them within int range");
  for (EdgeRecord& e : records.edges)
    if (e.to_point) e.to = static_cast<int>(e.landmark + offset);
}

// TORO's EQUIV records under Equivalences::kMerge: each chain of equivalent ids becomes its
// smallest id (pose_graph_file.hpp), before any vertex is added.
void merge_equivalences(Records& records, Equivalences mode, PoseGraphReadReport& report, const std::string& source,
                        RowLog& rows) {
  report.equivalences = records.equivalences.size();
  if (mode == Equivalences::kIgnore || records.equivalences.empty()) return;
  std::set<int> used;
  for (const VertexRecord& v : records.vertices) used.insert(v.id);
  for (const EdgeRecord& e : records.edges) used.insert({e.from, e.to});
  std::unordered_map<int, int> parent;
  // Union-find: a set's root is its smallest id (the larger root is linked under the smaller);
  // path compression keeps a long chain of EQUIV records near-linear instead of quadratic.
  auto root = [&](int id) {
    int r = id;
    for (auto it = parent.find(r); it != parent.end(); it = parent.find(r)) r = it->second;
    for (auto it = parent.find(id); it != parent.end() && it->second != r; it = parent.find(id))
      id = std::exchange(it->second, r);
    return r;
  };
  for (const auto& [line, pair] : records.equivalences) {
    rows.row([&, line = line, pair = pair] {
      for (const int id : {pair.first, pair.second})
        if (!used.count(id)) LineError(source, line).fail("EQUIV names unknown vertex " + std::to_string(id));
      const int a = root(pair.first), b = root(pair.second);
      if (a != b) parent[std::max(a, b)] = std::min(a, b);
    });
  }
  std::unordered_map<int, int> merged_into;  // every merged id -> its chain's smallest id
  for (const auto& entry : parent) merged_into[entry.first] = root(entry.first);
  report.merged_vertices = merged_into.size();
  auto target = [&](int id) {
    const auto it = merged_into.find(id);
    return it == merged_into.end() ? id : it->second;
  };
  records.vertices.erase(std::remove_if(records.vertices.begin(), records.vertices.end(),
                                        [&](const VertexRecord& v) { return merged_into.count(v.id) != 0; }),
                         records.vertices.end());
  for (EdgeRecord& e : records.edges) {
    e.from = target(e.from);
    e.to = target(e.to);
  }
  const std::size_t before = records.edges.size();
  records.edges.erase(std::remove_if(records.edges.begin(), records.edges.end(),
                                     [](const EdgeRecord& e) { return e.from == e.to; }),
                      records.edges.end());
  report.collapsed_edges = before - records.edges.size();
}

PoseGraph2D build(Records& records, PoseGraphFormat format, const std::string& source, RowLog& rows) {
  if (format == PoseGraphFormat::kIsam) separate_landmark_ids(records, source);
  PoseGraph2D graph;
  for (const VertexRecord& v : records.vertices) {
    rows.row([&] {
      at_line(source, v.line, "vertex " + std::to_string(v.id) + ": ", [&] {
        if (v.kind == VertexKind::kPose)
          graph.add_pose(v.id, v.value);
        else
          graph.add_point(v.id, v.value.head<2>());
      });
    });
  }
  // A file that lists vertices must list all of them: an unknown id in an edge is an error.
  if (records.vertices.empty()) add_missing_vertices(records, graph, source, rows);
  for (const EdgeRecord& e : records.edges) {
    if (e.skipped) continue;
    rows.row([&] {
      at_line(source, e.line, "", [&] {
        if (e.to_point)
          graph.add_point_edge(e.from, e.to, e.measurement.head<2>(), e.information.topLeftCorner<2, 2>());
        else
          graph.add_pose_edge(e.from, e.to, e.measurement, e.information);
      });
    });
  }
  for (const auto& fix : records.fixed) {
    rows.row([&] {
      for (const int id : fix.second)
        if (!graph.has_vertex(id)) LineError(source, fix.first).fail("FIX names unknown vertex " + std::to_string(id));
      for (const int id : fix.second) graph.set_fixed(id);
    });
  }
  return graph;
}

}  // namespace

PoseGraphRead parse_pose_graph(std::istream& in, const PoseGraphReadOptions& options, const std::string& source) {
  PoseGraphReadReport report;
  RowLog rows(options.rows, report);
  Records records;
  const PoseGraphFormat format = io_detail::read_graph_records(
      in, source, options.format, report, rows, records, "3-D",
      "use read_pose_graph_3d (Python: probslam.io.read_pose_graph_3d)", is_3d_tag, detect,
      [&](const Fields& fields, const std::string& tag, PoseGraphFormat f, long line, const LineError& err) {
        parse_line(fields, tag, f, own_noise(options.noise, f), line, err, records, rows);
      });
  merge_equivalences(records, options.equivalences, report, source, rows);
  PoseGraph2D graph = build(records, format, source, rows);
  rows.require_few_skipped();  // again: building may have skipped more
  return {std::move(graph), std::move(report)};
}

PoseGraph2D parse_pose_graph(std::istream& in, PoseGraphFormat format, const std::string& source) {
  PoseGraphReadOptions options;
  options.format = format;
  return std::move(parse_pose_graph(in, options, source).graph);
}

PoseGraphRead read_pose_graph(const std::string& path, const PoseGraphReadOptions& options) {
  std::ifstream in = io_detail::open_regular_file(path, "path");
  return parse_pose_graph(in, options, path);
}

PoseGraph2D read_pose_graph(const std::string& path, PoseGraphFormat format) {
  PoseGraphReadOptions options;
  options.format = format;
  return std::move(read_pose_graph(path, options).graph);
}

void write_g2o(std::ostream& out, const PoseGraph2D& graph) {
  out.precision(std::numeric_limits<double>::max_digits10);
  for (const GraphVertex& v : graph.vertices()) {
    if (v.kind == VertexKind::kPose)
      out << "VERTEX_SE2 " << v.id << ' ' << v.value[0] << ' ' << v.value[1] << ' ' << v.value[2] << '\n';
    else
      out << "VERTEX_XY " << v.id << ' ' << v.value[0] << ' ' << v.value[1] << '\n';
  }
  for (const GraphVertex& v : graph.vertices())
    if (v.fixed) out << "FIX " << v.id << '\n';
  for (const PoseEdge& e : graph.pose_edges()) {
    const Eigen::Matrix3d& i = e.information;
    out << "EDGE_SE2 " << graph.vertex(e.from).id << ' ' << graph.vertex(e.to).id << ' '
        << e.measurement[0] << ' ' << e.measurement[1] << ' ' << e.measurement[2] << ' ' << i(0, 0)
        << ' ' << i(0, 1) << ' ' << i(0, 2) << ' ' << i(1, 1) << ' ' << i(1, 2) << ' ' << i(2, 2)
        << '\n';
  }
  for (const PointEdge& e : graph.point_edges()) {
    const Eigen::Matrix2d& i = e.information;
    out << "EDGE_SE2_XY " << graph.vertex(e.pose).id << ' ' << graph.vertex(e.point).id << ' '
        << e.measurement[0] << ' ' << e.measurement[1] << ' ' << i(0, 0) << ' ' << i(0, 1) << ' '
        << i(1, 1) << '\n';
  }
}

namespace {

// iSAM's square-root information: the upper-triangular R with R^T R = information.
template <int N>
Eigen::Matrix<double, N, N> square_root(const Eigen::Matrix<double, N, N>& information) {
  const Eigen::LLT<Eigen::Matrix<double, N, N>> llt(information);
  if (llt.info() != Eigen::Success) throw_invalid_argument("graph", "holds an information matrix that is not positive definite");
  return llt.matrixU();
}

}  // namespace

void write_isam(std::ostream& out, const PoseGraph2D& graph) {
  std::set<int> landmarks;
  for (const GraphVertex& v : graph.vertices())
    if (v.kind == VertexKind::kPoint && !landmarks.insert(v.landmark_id).second)
      throw_invalid_argument("graph", "has two points with landmark id " + std::to_string(v.landmark_id) +
                                          ": iSAM needs one id per landmark");
  out.precision(std::numeric_limits<double>::max_digits10);
  std::vector<char> placed(graph.num_vertices(), 0);
  if (!graph.pose_edges().empty()) placed[graph.pose_edges().front().from] = 1;
  for (const PoseEdge& e : graph.pose_edges()) {
    // ODOMETRY introduces its second pose; EDGE2 joins two placed ones (a loop closure).
    const bool odometry = !placed[e.to] && placed[e.from];
    placed[e.from] = placed[e.to] = 1;
    const Eigen::Matrix3d r = square_root<3>(e.information);
    out << (odometry ? "ODOMETRY " : "EDGE2 ") << graph.vertex(e.from).id << ' ' << graph.vertex(e.to).id << ' '
        << e.measurement[0] << ' ' << e.measurement[1] << ' ' << e.measurement[2] << ' ' << r(0, 0) << ' '
        << r(0, 1) << ' ' << r(0, 2) << ' ' << r(1, 1) << ' ' << r(1, 2) << ' ' << r(2, 2) << '\n';
  }
  for (const PointEdge& e : graph.point_edges()) {
    const Eigen::Matrix2d r = square_root<2>(e.information);
    out << "LANDMARK " << graph.vertex(e.pose).id << ' ' << graph.vertex(e.point).landmark_id << ' '
        << e.measurement[0] << ' ' << e.measurement[1] << ' ' << r(0, 0) << ' ' << r(0, 1) << ' ' << r(1, 1)
        << '\n';
  }
}

void write_isam(const std::string& path, const PoseGraph2D& graph) {
  std::ostringstream text;  // all or nothing: a graph iSAM cannot hold leaves no file behind
  write_isam(text, graph);
  std::ofstream out(path);
  if (!out) throw std::invalid_argument("path: cannot write '" + path + "'");
  out << text.str();
  if (!out) throw std::invalid_argument("path: write to '" + path + "' failed");
}

void write_g2o(const std::string& path, const PoseGraph2D& graph) {
  std::ofstream out(path);
  if (!out) throw std::invalid_argument("path: cannot write '" + path + "'");
  write_g2o(out, graph);
  if (!out) throw std::invalid_argument("path: write to '" + path + "' failed");
}

}  // namespace probslam
