#include "probslam/io/pose_graph_file_3d.hpp"

#include <Eigen/Cholesky>
#include <array>
#include <algorithm>
#include <cmath>
#include <fstream>
#include <limits>
#include <map>
#include <set>
#include <sstream>
#include <unordered_map>
#include <vector>

#include "noise_information.hpp"
#include "pose_graph_row_log.hpp"
#include "text_fields.hpp"

namespace probslam {
namespace {

using io_detail::Fields;
using io_detail::LineError;
using io_detail::LineParseError;
using io_detail::own_noise;
using io_detail::RowLog;

// Squared norm of a quaternion that is unit to rounding: a few ulps of 1. Such a quaternion is
// kept as it is, so that a graph written with 17 digits reads back bit for bit.
constexpr double kUnitSquaredNormSlack = 8 * std::numeric_limits<double>::epsilon();

struct VertexRecord {
  long line;
  Vertex3D vertex;
};
struct EdgeRecord {
  long line;
  Edge3D edge;
  bool skipped = false;  // dead reckoning could not place it (kSkipAndCount)
};
struct PriorRecord {
  long line;
  int param;
  Prior3D prior;
};
struct PointRecord {
  long line;
  Point3D point;
};
struct PointEdgeRecord {
  long line;
  int param;
  PointEdge3D edge;
};
struct Records {
  std::vector<VertexRecord> vertices;
  std::vector<PointRecord> points;
  std::vector<PointEdgeRecord> point_edges;
  std::vector<EdgeRecord> edges;
  std::vector<PriorRecord> priors;
  std::vector<std::pair<long, std::vector<int>>> fixed;  // line, ids of one FIX record
  std::map<int, std::pair<long, Eigen::Matrix<double, 7, 1>>> params;  // PARAMS_SE3OFFSET: id -> line, x y z qx qy qz qw
};

const char* format_name(PoseGraphFormat format) {
  switch (format) {
    case PoseGraphFormat::kIsam: return "3-D iSAM";
    case PoseGraphFormat::kToro: return "3-D TORO";
    default: return "g2o 3-D";
  }
}

// Records of 2-D graphs: a 3-D reader given one says so and names the 2-D reader.
bool is_2d_tag(const std::string& tag) {
  static const std::set<std::string> tags = {"VERTEX_SE2", "VERTEX_XY", "EDGE_SE2", "EDGE_SE2_XY",
                                             "VERTEX2",    "EDGE2",     "ODOMETRY", "LANDMARK"};
  return tags.count(tag) != 0;
}

PoseGraphFormat detect(const std::string& tag) {
  if (tag == "VERTEX3") return PoseGraphFormat::kToro;
  if (tag == "EDGE3") return PoseGraphFormat::kIsam;
  return PoseGraphFormat::kG2o;
}

int vertex_id(const Fields& f, std::size_t i, const LineError& err) {
  const long id = f.integer(i);
  if (id < std::numeric_limits<int>::min() || id > std::numeric_limits<int>::max())
    err.fail("vertex id " + std::to_string(id) + " out of range");
  return static_cast<int>(id);
}

Eigen::Vector3d vector3(const Fields& f, std::size_t first, const char* what, const LineError& err) {
  const Eigen::Vector3d v(f.number(first), f.number(first + 1), f.number(first + 2));
  if (!v.allFinite()) err.fail(std::string(what) + " must be finite");
  return v;
}

// A unit quaternion from the file's qx qy qz qw (fields first..first+3), see
// kQuaternionNormTolerance.
Eigen::Quaterniond quaternion(const Fields& f, std::size_t first, const LineError& err) {
  const Eigen::Quaterniond q(f.number(first + 3), f.number(first), f.number(first + 1), f.number(first + 2));
  if (!q.coeffs().allFinite()) err.fail("quaternion must be finite");
  const double squared = q.squaredNorm();
  if (std::abs(squared - 1.0) <= kUnitSquaredNormSlack) return q;
  const double norm = std::sqrt(squared);
  if (!(std::abs(norm - 1.0) <= kQuaternionNormTolerance)) {
    std::ostringstream what;
    what << "quaternion (qx qy qz qw) has norm " << norm << ", not 1 (tolerance " << kQuaternionNormTolerance << ")";
    err.fail(what.str());
  }
  return Eigen::Quaterniond(q.coeffs() / norm);
}

// R = Rz(yaw) Ry(pitch) Rx(roll) from the file's roll pitch yaw (iSAM, GTSAM's Rot3::Ypr, TORO).
Eigen::Quaterniond from_roll_pitch_yaw(const Fields& f, std::size_t first, const LineError& err) {
  const Eigen::Vector3d rpy = vector3(f, first, "roll pitch yaw", err);
  Eigen::Quaterniond q = Eigen::AngleAxisd(rpy[2], Eigen::Vector3d::UnitZ()) *
                         Eigen::AngleAxisd(rpy[1], Eigen::Vector3d::UnitY()) *
                         Eigen::AngleAxisd(rpy[0], Eigen::Vector3d::UnitX());
  q.normalize();
  return q;
}

// The information the N (N + 1) / 2 upper-triangle entries (row-major, from field `first`) stand
// for, positive definite (repaired under the information-repair policy, counted in rows).
template <int N>
Eigen::Matrix<double, N, N> information(const Fields& f, std::size_t first, NoiseFormat noise, const LineError& err,
                                        RowLog& rows, long line) {
  using Matrix = Eigen::Matrix<double, N, N>;
  Matrix entries = Matrix::Zero();
  std::size_t k = first;
  for (int i = 0; i < N; ++i)
    for (int j = i; j < N; ++j) entries(i, j) = entries(j, i) = f.number(k++);
  const Matrix info = rows.repair<N>(io_detail::information_from<N>(entries, noise, err), line);
  const Eigen::LLT<Matrix> llt(info);
  if (llt.info() != Eigen::Success || !info.allFinite()) err.fail("information is not positive definite");
  return info;
}

void parse_line(const Fields& f, const std::string& tag, PoseGraphFormat format, NoiseFormat noise, long line,
                const LineError& err, Records& out, RowLog& rows) {
  auto edge_ends = [&](Edge3D& e) {
    e.from_id = vertex_id(f, 1, err);
    e.to_id = vertex_id(f, 2, err);
    if (e.from_id == e.to_id) err.fail("edge from vertex " + std::to_string(e.from_id) + " to itself");
  };
  if (format == PoseGraphFormat::kG2o) {
    if (tag == "VERTEX_SE3:QUAT") {
      f.need(9, "id x y z qx qy qz qw");
      Vertex3D v;
      v.id = vertex_id(f, 1, err);
      v.t = vector3(f, 2, "translation", err);
      v.q = quaternion(f, 5, err);
      out.vertices.push_back({line, v});
    } else if (tag == "EDGE_SE3:QUAT") {
      f.need(31, "i j x y z qx qy qz qw and 21 information entries");
      Edge3D e;
      edge_ends(e);
      e.t = vector3(f, 3, "translation", err);
      e.q = quaternion(f, 6, err);
      e.information = information<6>(f, 10, noise, err, rows, line);
      out.edges.push_back({line, e});
    } else if (tag == "EDGE_SE3_PRIOR") {
      f.need(31, "id param x y z qx qy qz qw and 21 information entries");
      PriorRecord p{line, vertex_id(f, 2, err), {}};
      p.prior.id = vertex_id(f, 1, err);
      p.prior.t = vector3(f, 3, "translation", err);
      p.prior.q = quaternion(f, 6, err);
      p.prior.information = information<6>(f, 10, noise, err, rows, line);
      out.priors.push_back(p);
    } else if (tag == "VERTEX_TRACKXYZ") {
      f.need(5, "id x y z");
      Point3D p;
      p.id = vertex_id(f, 1, err);
      p.p = vector3(f, 2, "point", err);
      out.points.push_back({line, p});
    } else if (tag == "EDGE_SE3_TRACKXYZ") {
      f.need(13, "pose point param x y z and 6 information entries");
      PointEdgeRecord r{line, vertex_id(f, 3, err), {}};
      r.edge.pose_id = vertex_id(f, 1, err);
      r.edge.point_id = vertex_id(f, 2, err);
      if (r.edge.pose_id == r.edge.point_id) err.fail("edge from vertex " + std::to_string(r.edge.pose_id) + " to itself");
      r.edge.z = vector3(f, 4, "measurement", err);
      // g2o's own convention for these records: the entries are the information (the NoiseFormat
      // option describes the pose records of the formats that differ).
      r.edge.information = information<3>(f, 7, NoiseFormat::kInformation, err, rows, line);
      out.point_edges.push_back(r);
    } else if (tag == "PARAMS_SE3OFFSET") {
      f.need(9, "id x y z qx qy qz qw");
      const int id = vertex_id(f, 1, err);
      Eigen::Matrix<double, 7, 1> offset;
      offset.head<3>() = vector3(f, 2, "translation", err);
      offset.tail<4>() = quaternion(f, 5, err).coeffs();  // x y z w
      if (!out.params.emplace(id, std::make_pair(line, offset)).second)
        err.fail("PARAMS_SE3OFFSET " + std::to_string(id) + " given twice");
    } else if (tag == "FIX") {
      f.need(2, "vertex ids");
      std::vector<int> ids;
      for (std::size_t i = 1; i < f.size(); ++i) ids.push_back(vertex_id(f, i, err));
      out.fixed.emplace_back(line, std::move(ids));
    } else {
      err.fail("unsupported g2o 3-D record '" + tag +
               "' (VERTEX_SE3:QUAT, EDGE_SE3:QUAT, EDGE_SE3_PRIOR, PARAMS_SE3OFFSET, VERTEX_TRACKXYZ, "
               "EDGE_SE3_TRACKXYZ, FIX)");
    }
    return;
  }
  // iSAM / GTSAM and TORO 3-D: Euler angles roll pitch yaw.
  if (tag == "VERTEX3") {
    f.need(8, "id x y z roll pitch yaw");
    Vertex3D v;
    v.id = vertex_id(f, 1, err);
    v.t = vector3(f, 2, "translation", err);
    v.q = from_roll_pitch_yaw(f, 5, err);
    out.vertices.push_back({line, v});
  } else if (tag == "EDGE3") {
    f.need(30, "i j x y z roll pitch yaw and 21 noise entries");
    Edge3D e;
    edge_ends(e);
    e.t = vector3(f, 3, "translation", err);
    e.q = from_roll_pitch_yaw(f, 6, err);
    e.information = information<6>(f, 9, noise, err, rows, line);
    out.edges.push_back({line, e});
  } else {
    err.fail(std::string("unsupported ") + format_name(format) + " record '" + tag + "' (VERTEX3 and EDGE3 only)");
  }
}

struct Pose {
  Eigen::Quaterniond q;
  Eigen::Vector3d t;
};

// Vertices of a file that lists none (iSAM): the first edge's first pose at the origin, then
// each edge composes its missing end from the placed one, in file order.
void dead_reckon(Records& records, PoseGraph3DData& graph, const std::string& source, RowLog& rows) {
  std::unordered_map<int, Pose> placed;
  auto place = [&](int id, const Pose& x) {
    placed.emplace(id, x);
    Vertex3D v;
    v.id = id;
    v.q = x.q;
    v.t = x.t;
    graph.vertices.push_back(v);
  };
  for (EdgeRecord& r : records.edges) {
    r.skipped = !rows.row([&] {
      const Edge3D& e = r.edge;
      if (placed.empty()) place(e.from_id, {Eigen::Quaterniond::Identity(), Eigen::Vector3d::Zero()});
      const auto from = placed.find(e.from_id), to = placed.find(e.to_id);
      if (from != placed.end() && to == placed.end()) {
        // x_to = x_from * z
        place(e.to_id, {(from->second.q * e.q).normalized(), from->second.t + from->second.q * e.t});
      } else if (from == placed.end() && to != placed.end()) {
        // x_from = x_to * z^-1
        const Eigen::Quaterniond zinv = e.q.conjugate();
        place(e.from_id, {(to->second.q * zinv).normalized(), to->second.t - to->second.q * (zinv * e.t)});
      } else if (from == placed.end()) {
        LineError(source, r.line)
            .fail("dead reckoning: vertices " + std::to_string(e.from_id) + " and " + std::to_string(e.to_id) +
                  " are not connected to the earlier records");
      }
    });
  }
}

PoseGraph3DData build(Records& records, const std::string& source, RowLog& rows) {
  PoseGraph3DData graph;
  std::unordered_map<int, std::size_t> index, point_index;  // one id space: an id is in one of them
  for (const VertexRecord& r : records.vertices) {
    rows.row([&] {
      if (!index.emplace(r.vertex.id, graph.vertices.size()).second)
        LineError(source, r.line).fail("vertex " + std::to_string(r.vertex.id) + " given twice");
      graph.vertices.push_back(r.vertex);
    });
  }
  for (const PointRecord& r : records.points) {
    rows.row([&] {
      if (index.count(r.point.id) != 0 || !point_index.emplace(r.point.id, graph.points.size()).second)
        LineError(source, r.line).fail("vertex " + std::to_string(r.point.id) + " given twice");
      graph.points.push_back(r.point);
    });
  }
  // A file that lists vertices must list all of them: an unknown id in an edge is an error.
  const bool listed = !records.vertices.empty();
  if (!listed) {
    dead_reckon(records, graph, source, rows);
    for (std::size_t i = 0; i < graph.vertices.size(); ++i) index.emplace(graph.vertices[i].id, i);
  }
  auto require_vertex = [&](int id, const LineError& err) {
    if (point_index.count(id) != 0) err.fail("vertex " + std::to_string(id) + " is a point (VERTEX_TRACKXYZ), not a pose");
    if (index.count(id) == 0) err.fail("unknown vertex " + std::to_string(id));
  };
  auto require_point = [&](int id, const LineError& err) {
    if (index.count(id) != 0) err.fail("vertex " + std::to_string(id) + " is a pose, not a point (VERTEX_TRACKXYZ)");
    if (point_index.count(id) == 0) err.fail("unknown point vertex " + std::to_string(id));
  };
  for (const EdgeRecord& r : records.edges) {
    if (r.skipped) continue;
    rows.row([&] {
      const LineError err(source, r.line);
      require_vertex(r.edge.from_id, err);
      require_vertex(r.edge.to_id, err);
      graph.edges.push_back(r.edge);
    });
  }
  for (const PriorRecord& r : records.priors) {
    rows.row([&] {
      const LineError err(source, r.line);
      require_vertex(r.prior.id, err);
      const auto param = records.params.find(r.param);
      if (param == records.params.end())
        err.fail("EDGE_SE3_PRIOR names parameter " + std::to_string(r.param) + ", which no PARAMS_SE3OFFSET defines");
      Eigen::Matrix<double, 7, 1> identity;
      identity << 0, 0, 0, 0, 0, 0, 1;
      if (param->second.second != identity)
        err.fail("EDGE_SE3_PRIOR through PARAMS_SE3OFFSET " + std::to_string(r.param) +
                 " (line " + std::to_string(param->second.first) +
                 "), which is not the identity: a prior on an offset sensor is not supported");
      graph.priors.push_back(r.prior);
    });
  }
  for (const PointEdgeRecord& r : records.point_edges) {
    rows.row([&] {
      const LineError err(source, r.line);
      require_vertex(r.edge.pose_id, err);
      require_point(r.edge.point_id, err);
      const auto param = records.params.find(r.param);
      if (param == records.params.end())
        err.fail("EDGE_SE3_TRACKXYZ names parameter " + std::to_string(r.param) +
                 ", which no PARAMS_SE3OFFSET defines");
      PointEdge3D e = r.edge;
      const Eigen::Matrix<double, 7, 1>& offset = param->second.second;
      e.offset_t = offset.head<3>();
      e.offset_q.coeffs() = offset.tail<4>();  // x y z w, as stored
      graph.point_edges.push_back(e);
    });
  }
  for (const auto& fix : records.fixed) {
    rows.row([&] {
      const LineError err(source, fix.first);
      for (const int id : fix.second)
        if (index.count(id) == 0 && point_index.count(id) == 0) err.fail("FIX names unknown vertex " + std::to_string(id));
      for (const int id : fix.second) {
        if (index.count(id) != 0)
          graph.vertices[index.at(id)].fixed = true;
        else
          graph.points[point_index.at(id)].fixed = true;
      }
    });
  }
  return graph;
}

}  // namespace

PoseGraph3DRead parse_pose_graph_3d(std::istream& in, const PoseGraphReadOptions& options, const std::string& source) {
  PoseGraphReadReport report;
  RowLog rows(options.rows, report);
  Records records;
  io_detail::read_graph_records(
      in, source, options.format, report, rows, records, "2-D",
      "use read_pose_graph (Python: probslam.graph.read_pose_graph)", is_2d_tag, detect,
      [&](const Fields& fields, const std::string& tag, PoseGraphFormat f, long line, const LineError& err) {
        parse_line(fields, tag, f, own_noise(options.noise, f), line, err, records, rows);
      });
  PoseGraph3DData graph = build(records, source, rows);
  rows.require_few_skipped();  // again: building may have skipped more
  return {std::move(graph), std::move(report)};
}

PoseGraph3DRead read_pose_graph_3d(const std::string& path, const PoseGraphReadOptions& options) {
  std::ifstream in = io_detail::open_regular_file(path, "path");
  return parse_pose_graph_3d(in, options, path);
}

namespace {

void write_pose(std::ostream& out, const Eigen::Quaterniond& q, const Eigen::Vector3d& t) {
  out << t.x() << ' ' << t.y() << ' ' << t.z() << ' ' << q.x() << ' ' << q.y() << ' ' << q.z() << ' ' << q.w();
}

template <int N>
void write_information(std::ostream& out, const Eigen::Matrix<double, N, N>& information) {
  for (int i = 0; i < N; ++i)
    for (int j = i; j < N; ++j) out << ' ' << information(i, j);
}

// A point edge's sensor offset as a PARAMS_SE3OFFSET record holds it: x y z qx qy qz qw.
Eigen::Matrix<double, 7, 1> offset_record(const PointEdge3D& e) {
  Eigen::Matrix<double, 7, 1> o;
  o << e.offset_t, e.offset_q.coeffs();
  return o;
}

// The sensor offsets to write as PARAMS_SE3OFFSET records: the identity first (parameter 0, the
// priors'), then each distinct offset of a point edge in order; and each point edge's parameter.
struct Offsets {
  std::vector<Eigen::Matrix<double, 7, 1>> records;
  std::vector<std::size_t> of_edge;
};

Offsets offsets_of(const PoseGraph3DData& graph) {
  Offsets out;
  out.records.resize(1);
  out.records[0] << 0, 0, 0, 0, 0, 0, 1;
  // Keyed by the record's values (== as Eigen compares them: finite, so an ordered map finds the
  // same ones); a lookup per edge, not a scan of the offsets seen so far.
  std::map<std::array<double, 7>, std::size_t> index;
  auto key = [](const Eigen::Matrix<double, 7, 1>& o) {
    std::array<double, 7> k{};
    std::copy(o.data(), o.data() + 7, k.begin());
    return k;
  };
  index.emplace(key(out.records[0]), 0);
  for (const PointEdge3D& e : graph.point_edges) {
    const Eigen::Matrix<double, 7, 1> o = offset_record(e);
    const auto [it, added] = index.emplace(key(o), out.records.size());
    if (added) out.records.push_back(o);
    out.of_edge.push_back(it->second);
  }
  return out;
}

void check_writable(const PoseGraph3DData& graph) {
  std::set<int> ids;
  for (const Vertex3D& v : graph.vertices)
    if (!ids.insert(v.id).second) throw_invalid_argument("graph", "has vertex " + std::to_string(v.id) + " twice");
  auto known = [&](int id, const char* what) {
    if (ids.count(id) == 0)
      throw_invalid_argument("graph", std::string("has ") + what + " naming unknown vertex " + std::to_string(id));
  };
  for (const Edge3D& e : graph.edges) {
    known(e.from_id, "an edge");
    known(e.to_id, "an edge");
  }
  for (const Prior3D& p : graph.priors) known(p.id, "a prior");
  std::set<int> points;
  for (const Point3D& p : graph.points)
    if (ids.count(p.id) != 0 || !points.insert(p.id).second)
      throw_invalid_argument("graph", "has vertex " + std::to_string(p.id) + " twice");
  for (const PointEdge3D& e : graph.point_edges) {
    known(e.pose_id, "a point edge");
    if (points.count(e.point_id) == 0)
      throw_invalid_argument("graph", "has a point edge naming unknown point " + std::to_string(e.point_id));
    if (!e.offset_q.coeffs().allFinite() || !e.offset_t.allFinite() ||
        !(std::abs(e.offset_q.norm() - 1.0) <= kQuaternionNormTolerance))
      throw_invalid_argument("graph", "has a point edge whose sensor offset is not finite with a unit quaternion");
  }
}

}  // namespace

void write_g2o_3d(std::ostream& out, const PoseGraph3DData& graph) {
  check_writable(graph);
  out.precision(std::numeric_limits<double>::max_digits10);
  for (const Vertex3D& v : graph.vertices) {
    out << "VERTEX_SE3:QUAT " << v.id << ' ';
    write_pose(out, v.q, v.t);
    out << '\n';
  }
  for (const Point3D& p : graph.points)
    out << "VERTEX_TRACKXYZ " << p.id << ' ' << p.p.x() << ' ' << p.p.y() << ' ' << p.p.z() << '\n';
  for (const Vertex3D& v : graph.vertices)
    if (v.fixed) out << "FIX " << v.id << '\n';
  for (const Point3D& p : graph.points)
    if (p.fixed) out << "FIX " << p.id << '\n';
  for (const Edge3D& e : graph.edges) {
    out << "EDGE_SE3:QUAT " << e.from_id << ' ' << e.to_id << ' ';
    write_pose(out, e.q, e.t);
    write_information(out, e.information);
    out << '\n';
  }
  const Offsets offsets = offsets_of(graph);
  if (!graph.priors.empty() || !graph.point_edges.empty())
    for (size_t k = 0; k < offsets.records.size(); ++k) {
      out << "PARAMS_SE3OFFSET " << k;
      for (int i = 0; i < 7; ++i) out << ' ' << offsets.records[k][i];
      out << '\n';
    }
  for (const Prior3D& p : graph.priors) {
    out << "EDGE_SE3_PRIOR " << p.id << " 0 ";
    write_pose(out, p.q, p.t);
    write_information(out, p.information);
    out << '\n';
  }
  for (size_t k = 0; k < graph.point_edges.size(); ++k) {
    const PointEdge3D& e = graph.point_edges[k];
    out << "EDGE_SE3_TRACKXYZ " << e.pose_id << ' ' << e.point_id << ' ' << offsets.of_edge[k] << ' ' << e.z.x() << ' ' << e.z.y()
        << ' ' << e.z.z();
    write_information(out, e.information);
    out << '\n';
  }
}

void write_g2o_3d(const std::string& path, const PoseGraph3DData& graph) {
  std::ostringstream text;  // all or nothing: a graph that cannot be written leaves no file behind
  write_g2o_3d(text, graph);
  std::ofstream out(path);
  if (!out) throw std::invalid_argument("path: cannot write '" + path + "'");
  out << text.str();
  if (!out) throw std::invalid_argument("path: write to '" + path + "' failed");
}

}  // namespace probslam
