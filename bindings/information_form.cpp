#include <pybind11/stl.h>


#include "numpy.hpp"
#include "probslam/graph/eif_correspondence.hpp"
#include "probslam/graph/information_form.hpp"

namespace probslam::bindings {

namespace {

using IndexArray = py::array_t<int, py::array::c_style | py::array::forcecast>;

// scipy.sparse CSC parts (indptr, indices, data, shape) <-> Eigen column-compressed matrices.
SparseMatrixd sparse_from_csc(py::handle indptr_obj, py::handle indices_obj, py::handle data_obj,
                              int rows, int cols, const char* name) {
  IndexArray indptr = IndexArray::ensure(indptr_obj), indices = IndexArray::ensure(indices_obj);
  DoubleArray data = as_array(data_obj, name);
  if (rows < 0 || cols < 0 || !indptr || !indices || indptr.ndim() != 1 || indices.ndim() != 1 ||
      data.ndim() != 1 || indptr.shape(0) != static_cast<py::ssize_t>(cols) + 1 || indices.shape(0) != data.shape(0) ||
      indptr.at(0) != 0 || indptr.at(cols) != data.shape(0))
    throw py::value_error(std::string(name) + " is not a consistent CSC matrix");
  // Eigen reads the arrays as they are: column starts must not decrease and the row indices of a
  // column must increase strictly (scipy's canonical form), or it reads out of bounds.
  for (int c = 0; c < cols; ++c) {
    if (indptr.at(c + 1) < indptr.at(c))
      throw py::value_error(std::string(name) + " has decreasing column starts (indptr)");
    for (int k = indptr.at(c); k < indptr.at(c + 1); ++k)
      if (indices.at(k) < 0 || indices.at(k) >= rows || (k > indptr.at(c) && indices.at(k) <= indices.at(k - 1)))
        throw py::value_error(std::string(name) +
                              " has a row index outside the matrix or out of order (sum duplicates and sort)");
  }
  const Eigen::Map<const SparseMatrixd> map(rows, cols, data.shape(0), indptr.data(), indices.data(),
                                            data.data());
  SparseMatrixd out = map;  // also sorts nothing: scipy's canonical CSC has sorted indices
  return out;
}

py::tuple sparse_to_csc(const SparseMatrixd& m) {
  const py::ssize_t nnz = m.nonZeros();
  py::array_t<int> indptr(m.cols() + 1), indices(nnz);
  py::array_t<double> data(nnz);
  std::copy(m.outerIndexPtr(), m.outerIndexPtr() + m.cols() + 1, indptr.mutable_data());
  std::copy(m.innerIndexPtr(), m.innerIndexPtr() + nnz, indices.mutable_data());
  std::copy(m.valuePtr(), m.valuePtr() + nnz, data.mutable_data());
  return py::make_tuple(data, indices, indptr, py::make_tuple(m.rows(), m.cols()));
}

Eigen::VectorXi int_vector(py::handle obj, const char* name, py::ssize_t size) {
  const LongArray a = integer_array_arg(obj, name);
  if (a.ndim() != 1 || a.shape(0) != size)
    throw py::value_error(std::string(name) + " must have shape (" + std::to_string(size) + ",)");
  const std::vector<int> entries = int_entries(a, name, "index");
  return Eigen::Map<const Eigen::VectorXi>(entries.data(), size);
}

FeatureMeasurements measurements_arg(py::handle time, py::handle z, py::handle correspondences) {
  DoubleArray za = as_array(z, "z");
  if (za.ndim() != 2 || (za.shape(1) != 2 && za.shape(1) != 3))
    throw py::value_error("z must have shape (M, 2) or (M, 3), got " + shape_of(za));
  FeatureMeasurements m;
  m.z = as_matrix(za);
  m.time = int_vector(time, "time", za.shape(0));
  m.feature = int_vector(correspondences, "correspondences", za.shape(0));
  return m;
}

Eigen::VectorXd dt_arg(py::handle dt, py::ssize_t steps) {
  DoubleArray a = as_array(dt, "dt");
  if (a.ndim() == 0) return Eigen::VectorXd::Constant(steps, *a.data());
  if (a.ndim() != 1 || a.shape(0) != steps)
    throw py::value_error("dt must be a number or have shape (" + std::to_string(steps) + ",)");
  return as_vector(a);
}

// num_poses sizes the path block 3 num_poses: checked against omega's size before it is used
// (a huge value would overflow the product).
void require_num_poses(int num_poses, int dim) {
  if (num_poses <= 0 || num_poses > dim / 3)
    throw py::value_error("num_poses must be in 1 .. " + std::to_string(dim / 3) + " for omega of size " +
                          std::to_string(dim) + ", got " + std::to_string(num_poses));
}

InformationForm form_from(py::handle indptr, py::handle indices, py::handle data, int dim, Eigen::VectorXd xi,
                          int num_poses, int feature_dim) {
  require_num_poses(num_poses, dim);
  InformationForm f;
  f.omega = sparse_from_csc(indptr, indices, data, dim, dim, "omega");
  f.xi = std::move(xi);
  f.num_poses = num_poses;
  f.feature_dim = feature_dim;
  return f;
}

InformationForm form_arg(py::handle indptr, py::handle indices, py::handle data, int dim, py::handle xi,
                         int num_poses, int feature_dim) {
  return form_from(indptr, indices, data, dim, as_vector(vector_arg(xi, "xi", dim)), num_poses, feature_dim);
}

py::array_t<double> blocks_array(const std::vector<Eigen::Matrix3d>& blocks) {
  py::array_t<double> out({static_cast<py::ssize_t>(blocks.size()), py::ssize_t{3}, py::ssize_t{3}});
  auto r = out.mutable_unchecked<3>();
  for (size_t k = 0; k < blocks.size(); ++k)
    for (int i = 0; i < 3; ++i)
      for (int j = 0; j < 3; ++j) r(k, i, j) = blocks[k](i, j);
  return out;
}

py::dict slam_dict(const GraphSlamResult& r) {
  py::dict out;
  out["poses"] = r.poses;
  out["features"] = r.features;
  out["pose_covariances"] = blocks_array(r.pose_covariances);
  out["iterations"] = r.iterations;
  out["converged"] = r.converged;
  out["objective"] = r.objective;
  return out;
}

GraphSlamOptions slam_options(int max_iterations, double tolerance, py::handle initial_pose, bool path_covariances) {
  GraphSlamOptions o;
  o.max_iterations = max_iterations;
  o.tolerance = tolerance;
  o.initial_pose = pose_arg(initial_pose, "initial_pose");
  o.path_covariances = path_covariances;
  return o;
}

py::dict merges_dict(const std::vector<FeatureMerge>& merges) {
  const auto k = static_cast<py::ssize_t>(merges.size());
  py::array_t<int> round(k), kept(k), merged(k);
  py::array_t<double> probability(k), distance2(k);
  for (py::ssize_t i = 0; i < k; ++i) {
    const FeatureMerge& f = merges[static_cast<size_t>(i)];
    round.mutable_at(i) = f.round;
    kept.mutable_at(i) = f.kept;
    merged.mutable_at(i) = f.merged;
    probability.mutable_at(i) = f.probability;
    distance2.mutable_at(i) = f.distance2;
  }
  py::dict out;
  out["round"] = round;
  out["kept"] = kept;
  out["merged"] = merged;
  out["probability"] = probability;
  out["distance2"] = distance2;
  return out;
}

}  // namespace

void define_information_form(py::module_& m) {
  m.def("_eif_initialize",
        [](py::handle controls, py::handle dt, py::handle initial_pose) {
          DoubleArray u = matrix_arg(controls, "controls", 2);
          return Poses2(eif_initialize(as_matrix(u), dt_arg(dt, u.shape(0)), pose_arg(initial_pose, "initial_pose")));
        });
  m.def("_eif_construct", [](py::handle controls, py::handle dt, py::handle time, py::handle z,
                             py::handle correspondences, py::handle poses, py::handle features, py::handle R,
                             py::handle Q) {
    DoubleArray u = matrix_arg(controls, "controls", 2);
    const FeatureMeasurements meas = measurements_arg(time, z, correspondences);
    DoubleArray p = matrix_arg(poses, "poses", 3);
    DoubleArray f = as_array(features, "features");
    if (f.ndim() != 2) throw py::value_error("features must have shape (N, d)");
    InformationForm form;
    {
      const Eigen::VectorXd steps = dt_arg(dt, u.shape(0));
      const Eigen::Matrix3d r = Eigen::Matrix3d(square_matrix_arg(R, "R", 3));
      const Eigen::MatrixXd q = square_matrix_arg(Q, "Q");
      py::gil_scoped_release release;
      form = eif_construct(as_matrix(u), steps, meas, as_matrix(p), as_matrix(f), r, q);
    }
    return py::make_tuple(sparse_to_csc(form.omega), form.xi);
  });
  m.def("_eif_initial_features", [](py::handle poses, py::handle time, py::handle z, py::handle correspondences,
                                    int num_features) {
    DoubleArray p = matrix_arg(poses, "poses", 3);
    return RowMatrixXd(eif_initial_features(as_matrix(p), measurements_arg(time, z, correspondences), num_features));
  });
  m.def("_eif_reduce", [](py::handle indptr, py::handle indices, py::handle data, int dim, py::handle xi,
                          int num_poses, int feature_dim) {
    const InformationForm form = form_arg(indptr, indices, data, dim, xi, num_poses, feature_dim);
    ReducedInformationForm reduced;
    {
      py::gil_scoped_release release;
      reduced = eif_reduce(form);
    }
    return py::make_tuple(sparse_to_csc(reduced.omega), reduced.xi);
  });
  m.def("_eif_solve", [](py::handle r_indptr, py::handle r_indices, py::handle r_data, py::handle r_xi,
                         py::handle indptr, py::handle indices, py::handle data, int dim, py::handle xi,
                         int num_poses, int feature_dim, const std::vector<std::pair<int, int>>& blocks) {
    const InformationForm form = form_arg(indptr, indices, data, dim, xi, num_poses, feature_dim);
    ReducedInformationForm reduced;
    const int p = 3 * num_poses;
    reduced.omega = sparse_from_csc(r_indptr, r_indices, r_data, p, p, "reduced_omega");
    reduced.xi = as_vector(vector_arg(r_xi, "reduced_xi", p));
    EifSolution sol;
    {
      py::gil_scoped_release release;
      sol = eif_solve(reduced, form, blocks);
    }
    return py::make_tuple(sol.poses, sol.features, blocks_array(sol.covariance_blocks));
  });
  m.def("_graph_slam", [](py::handle controls, py::handle dt, py::handle time, py::handle z,
                          py::handle correspondences, py::handle R, py::handle Q, int max_iterations,
                          double tolerance, py::handle initial_pose, bool path_covariances) {
    DoubleArray u = matrix_arg(controls, "controls", 2);
    const FeatureMeasurements meas = measurements_arg(time, z, correspondences);
    const GraphSlamOptions o = slam_options(max_iterations, tolerance, initial_pose, path_covariances);
    GraphSlamResult r;
    {
      const Eigen::VectorXd steps = dt_arg(dt, u.shape(0));
      const Eigen::Matrix3d rm = Eigen::Matrix3d(square_matrix_arg(R, "R", 3));
      const Eigen::MatrixXd qm = square_matrix_arg(Q, "Q");
      py::gil_scoped_release release;
      r = graph_slam(as_matrix(u), steps, meas, rm, qm, o);
    }
    return slam_dict(r);
  });
  m.def("_eif_correspondence_test", [](py::handle indptr, py::handle indices, py::handle data, int dim,
                                       py::handle r_indptr, py::handle r_indices, py::handle r_data,
                                       py::handle features, int num_poses,
                                       const std::vector<std::pair<int, int>>& pairs) {
    DoubleArray f = as_array(features, "features");
    if (f.ndim() != 2 || (f.shape(1) != 2 && f.shape(1) != 3))
      throw py::value_error("features must have shape (N, 2) or (N, 3), got " + shape_of(f));
    const int d = static_cast<int>(f.shape(1));
    // Table 11.8 reads Omega alone: xi is not needed.
    // xi is sized only once omega's arrays have vouched for dim.
    InformationForm form = form_from(indptr, indices, data, dim, Eigen::VectorXd(), num_poses, d);
    form.xi = Eigen::VectorXd::Zero(dim);
    const int p = 3 * num_poses;
    const SparseMatrixd reduced = sparse_from_csc(r_indptr, r_indices, r_data, p, p, "reduced_omega");
    const auto k = static_cast<py::ssize_t>(pairs.size());
    py::array_t<double> probability(k), distance2(k), mean({k, py::ssize_t{d}}), cov({k, py::ssize_t{d}, py::ssize_t{d}});
    std::vector<CorrespondenceTest> tests;
    {
      const RowMatrixXd means = as_matrix(f);
      py::gil_scoped_release release;
      SparseCholesky factor;
      eif_factorize_path(reduced, factor);
      EifCorrespondenceTester tester(form, factor, means);
      for (const auto& [j, kk] : pairs) tests.push_back(tester.test(j, kk));
    }
    for (py::ssize_t i = 0; i < k; ++i) {
      const CorrespondenceTest& t = tests[static_cast<size_t>(i)];
      probability.mutable_at(i) = t.probability;
      distance2.mutable_at(i) = t.distance2;
      for (int r = 0; r < d; ++r) {
        mean.mutable_at(i, r) = t.mean[r];
        for (int c = 0; c < d; ++c) cov.mutable_at(i, r, c) = t.covariance(r, c);
      }
    }
    return py::make_tuple(probability, distance2, mean, cov);
  });
  m.def("_graph_slam_unknown", [](py::handle controls, py::handle dt, py::handle time, py::handle z,
                                  py::handle R, py::handle Q, int max_iterations, double tolerance,
                                  py::handle initial_pose, bool path_covariances, double chi,
                                  double search_radius, int max_rounds) {
    DoubleArray u = matrix_arg(controls, "controls", 2);
    DoubleArray za = as_array(z, "z");
    py::array_t<long> unknown(za.ndim() == 2 ? za.shape(0) : 0);  // ignored: Table 11.9 line 2
    std::fill_n(unknown.mutable_data(), unknown.size(), 0L);
    const FeatureMeasurements meas = measurements_arg(time, z, unknown);
    const GraphSlamOptions o = slam_options(max_iterations, tolerance, initial_pose, path_covariances);
    CorrespondenceSearchOptions search;
    search.chi = chi;
    search.search_radius = search_radius;
    search.max_rounds = max_rounds;
    GraphSlamUnknownResult r;
    {
      const Eigen::VectorXd steps = dt_arg(dt, u.shape(0));
      const Eigen::Matrix3d rm = Eigen::Matrix3d(square_matrix_arg(R, "R", 3));
      const Eigen::MatrixXd qm = square_matrix_arg(Q, "Q");
      py::gil_scoped_release release;
      r = graph_slam_unknown(as_matrix(u), steps, meas, rm, qm, o, search);
    }
    py::dict out = slam_dict(r.slam);
    out["correspondences"] = Eigen::VectorXi(r.correspondences);
    out["merges"] = merges_dict(r.merges);
    out["rounds"] = r.rounds;
    out["search_converged"] = r.converged;
    return out;
  });
  m.def("_eif_objective", [](py::handle controls, py::handle dt, py::handle time, py::handle z,
                             py::handle correspondences, py::handle poses, py::handle features, py::handle R,
                             py::handle Q) {
    DoubleArray u = matrix_arg(controls, "controls", 2);
    DoubleArray p = matrix_arg(poses, "poses", 3);
    DoubleArray f = as_array(features, "features");
    if (f.ndim() != 2) throw py::value_error("features must have shape (N, d)");
    return eif_objective(as_matrix(u), dt_arg(dt, u.shape(0)), measurements_arg(time, z, correspondences),
                         as_matrix(p), as_matrix(f), Eigen::Matrix3d(square_matrix_arg(R, "R", 3)), square_matrix_arg(Q, "Q"));
  });
}

}  // namespace probslam::bindings
