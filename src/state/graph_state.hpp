#pragma once
// What the 2-D and 3-D pose graphs' states share (docs/file_format.md): a vertex's kind as one
// byte, vertex ids read once each, edges' vertex indices checked against the vertices read, and
// their information checked as adding them checks it.
#include <string>
#include <unordered_map>
#include <vector>

#include "probslam/core/check.hpp"
#include "probslam/core/state_file.hpp"
#include "probslam/graph/vertex_kind.hpp"

namespace probslam::state_detail {

// The information matrices were symmetrised when added; a stored one that is not SPD at this
// tolerance was not written by save.
inline constexpr double kStoredSymmetryTolerance = 1e-6;

inline void write_vertex_kind(StateWriter& w, VertexKind kind) { w.u8(kind == VertexKind::kPose ? 0 : 1); }

inline VertexKind read_vertex_kind(StateReader& r) {
  const std::uint8_t kind = r.u8();
  if (kind > 1) r.fail("a vertex kind is " + std::to_string(kind));
  return kind == 0 ? VertexKind::kPose : VertexKind::kPoint;
}

/// Records vertex `index`'s id, refusing one read before.
inline void index_vertex_id(StateReader& r, std::unordered_map<int, int>& index_of_id, int id, std::size_t index) {
  if (!index_of_id.emplace(id, static_cast<int>(index)).second) r.fail("vertex id " + std::to_string(id) + " is repeated");
}

/// Checks a stored edge's (or prior's) information as adding the edge checks it: symmetric
/// positive definite; `what` names the edge in the error.
template <typename Matrix>
void check_information(const StateReader& r, const char* what, const Matrix& information) {
  validated(r, what, [&] { require_symmetric_positive_definite(information, "information", kStoredSymmetryTolerance); });
}

/// An edge's end: a vertex index, which must name a vertex of `kind` among `vertices`.
template <typename Vertex>
int read_vertex_index(StateReader& r, const std::vector<Vertex>& vertices, VertexKind kind, const char* what) {
  const int index = r.i32();
  if (index < 0 || static_cast<std::size_t>(index) >= vertices.size() ||
      vertices[static_cast<std::size_t>(index)].kind != kind)
    r.fail(std::string("an edge's ") + what + " index " + std::to_string(index) + " names no " + what);
  return index;
}

}  // namespace probslam::state_detail
