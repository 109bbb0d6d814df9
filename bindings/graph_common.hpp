#pragma once
// What the bindings of PoseGraph2D and PoseGraph3D share, written once for either graph type: the
// ids of a kind of vertex, the end ids of edges, set_poses / set_points' arguments, and the
// methods both classes have with the same arguments and meaning. Each reads the graph under its
// lock (object_lock.hpp) and builds the Python objects after.
#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>

#include <algorithm>
#include <string>
#include <utility>
#include <vector>

#include "args.hpp"
#include "graph_options.hpp"  // vertex_ids_arg
#include "numpy.hpp"
#include "object_lock.hpp"
#include "probslam/graph/vertex_kind.hpp"

namespace probslam::bindings {

/// An (n, 2) int64 array of the id pairs in `flat` (2n entries).
inline py::array_t<long> id_pairs(const std::vector<long>& flat) {
  py::array_t<long> out({static_cast<py::ssize_t>(flat.size() / 2), py::ssize_t{2}});
  std::copy(flat.begin(), flat.end(), out.mutable_data());
  return out;
}

/// (P,) int64 ids of the vertices of one kind in the order they were added; id_of(vertex) reads
/// the id (a 2-D graph's landmark_ids read the points' iSAM numbers).
template <class Graph, class IdOf>
py::array_t<long> ids_of(const Graph& g, VertexKind kind, IdOf id_of) {
  const std::vector<long> ids = locked(g, [&] {
    std::vector<long> out;
    for (const auto& v : g.vertices())
      if (v.kind == kind) out.push_back(id_of(v));
    return out;
  });
  return py::array_t<long>(static_cast<py::ssize_t>(ids.size()), ids.data());
}

template <class Graph>
py::array_t<long> ids_of(const Graph& g, VertexKind kind) {
  return ids_of(g, kind, [](const auto& v) { return static_cast<long>(v.id); });
}

/// (E + M, 2) int64 end ids of every edge: the pose edges (from, to), then the point edges
/// (pose, point).
template <class Graph>
py::array_t<long> all_edge_ids(const Graph& g) {
  return id_pairs(locked(g, [&] {
    std::vector<long> out;
    for (const auto& e : g.pose_edges()) out.insert(out.end(), {g.vertex(e.from).id, g.vertex(e.to).id});
    for (const auto& e : g.point_edges()) out.insert(out.end(), {g.vertex(e.pose).id, g.vertex(e.point).id});
    return out;
  }));
}

/// The end ids (E, 2) of `live`, one of the graph's edge lists (ends(e): the edge's two vertex
/// indices), and a copy of those edges, both read under the graph's lock.
template <class Graph, class Edge, class Ends>
std::pair<py::array_t<long>, std::vector<Edge>> edges_with_ids(const Graph& g, const std::vector<Edge>& live,
                                                               Ends ends) {
  std::vector<long> flat;
  std::vector<Edge> edges = locked(g, [&] {
    for (const Edge& e : live) {
      const auto [a, b] = ends(e);
      flat.insert(flat.end(), {g.vertex(a).id, g.vertex(b).id});
    }
    return live;
  });
  return {id_pairs(flat), std::move(edges)};
}

/// set_poses / set_points' arguments: ids (N,) and the (N, width) array `name` of their values.
struct RowsPerId {
  std::vector<int> ids;
  DoubleArray rows;
};

inline RowsPerId rows_per_id(py::handle ids_obj, py::handle rows_obj, const char* name, int width) {
  RowsPerId out{vertex_ids_arg(ids_obj, "ids"), matrix_arg(rows_obj, name, width)};
  if (out.rows.shape(0) != static_cast<py::ssize_t>(out.ids.size()))
    throw py::value_error(std::string(name) + " must have one row per id");
  return out;
}

/// The methods PoseGraph2D and PoseGraph3D both have, with the same arguments and meaning.
template <class Graph>
void define_common_graph_methods(py::class_<Graph>& c, const char* has_vertex_doc) {
  c.def("set_fixed",
        [](Graph& g, IntArg id, BoolArg fixed_arg) {
          const int i = id.get("id");
          const bool fixed = fixed_arg.get("fixed");
          locked(g, [&] { g.set_fixed(i, fixed); });
        },
        py::arg("id"), py::arg("fixed") = true,
        "A fixed vertex keeps its value when optimising (the gauge); with none fixed, optimisers hold\n"
        "the first pose.")
      .def("is_fixed",
           [](const Graph& g, IntArg id) {
             const int i = id.get("id");
             return locked(g, [&] { return g.vertex(g.index_of(i)).fixed; });
           },
           py::arg("id"), "Whether vertex id is fixed.")
      .def("has_vertex",
           [](const Graph& g, IntArg id) {
             const int i = id.get("id");
             return locked(g, [&] { return g.has_vertex(i); });
           },
           py::arg("id"), has_vertex_doc)
      .def_property_readonly("num_vertices", getter(&Graph::num_vertices), "Poses plus points.")
      .def_property_readonly("num_pose_edges",
                             [](const Graph& g) { return locked(g, [&] { return g.pose_edges().size(); }); },
                             "Number of pose-pose edges.")
      .def_property_readonly("num_point_edges",
                             [](const Graph& g) { return locked(g, [&] { return g.point_edges().size(); }); },
                             "Number of pose-point edges.")
      .def_property_readonly("pose_ids", [](const Graph& g) { return ids_of(g, VertexKind::kPose); },
                             "(P,) int64 ids of the pose vertices, in the order they were added.")
      .def_property_readonly("point_ids", [](const Graph& g) { return ids_of(g, VertexKind::kPoint); },
                             "(L,) int64 ids of the point vertices, in the order they were added.")
      .def("copy", [](const Graph& g) { return locked(g, [&] { return Graph(g); }); }, "An independent deep copy.");
}

}  // namespace probslam::bindings
