#include "landmarks.hpp"

#include <string>

#include "repr.hpp"

namespace probslam::bindings {

LandmarkArrays landmark_arrays(const std::vector<LandmarkEntry>& entries) {
  const auto n = static_cast<py::ssize_t>(entries.size());
  LandmarkArrays out{py::array_t<long>(n), py::array_t<double>({n, py::ssize_t{2}}),
                     py::array_t<double>({n, py::ssize_t{2}, py::ssize_t{2}})};
  auto ids = out.ids.mutable_unchecked<1>();
  auto means = out.means.mutable_unchecked<2>();
  auto covs = out.covariances.mutable_unchecked<3>();
  for (py::ssize_t i = 0; i < n; ++i) {
    const LandmarkEntry& e = entries[static_cast<std::size_t>(i)];
    ids(i) = e.id;
    for (int a = 0; a < 2; ++a) {
      means(i, a) = e.mean[a];
      for (int b = 0; b < 2; ++b) covs(i, a, b) = e.cov(a, b);
    }
  }
  return out;
}

DoubleArray measurements_arg(int landmark_dim, py::handle z) {
  DoubleArray a = as_array(z, "z");
  if (a.ndim() == 1 && a.shape(0) == landmark_dim) return DoubleArray(a.reshape({py::ssize_t{1}, a.shape(0)}));
  return matrix_arg(z, "z", landmark_dim);
}

std::vector<long> ids_arg(py::handle ids, py::ssize_t k) {
  LongArray a = integer_array_arg(ids, "ids");
  if (a.ndim() == 0) a = a.reshape({py::ssize_t{1}});
  if (a.ndim() != 1 || a.shape(0) != k)
    throw py::value_error("ids must have shape (" + std::to_string(k) + ",), one id per measurement");
  return std::vector<long>(a.data(), a.data() + a.shape(0));
}

void define_landmarks(py::module_& m) {
  py::class_<LandmarkArrays>(m, "Landmarks",
                             "One map's landmarks (EkfSlam.landmarks(), FastSlam.landmarks(particle)): ids,\n"
                             "means and covariances, row i one landmark. len() is the number of landmarks.")
      .def_readonly("ids", &LandmarkArrays::ids, "(N,) int64 landmark ids.")
      .def_readonly("means", &LandmarkArrays::means, "(N, 2) positions (x, y), metres.")
      .def_readonly("covariances", &LandmarkArrays::covariances, "(N, 2, 2) position covariances, m^2.")
      .def("__len__", [](const LandmarkArrays& l) { return l.ids.shape(0); })
      .def("__repr__", [](py::handle self) {
        return repr_of(self, std::to_string(self.cast<const LandmarkArrays&>().ids.shape(0)) + " landmarks");
      });
}

}  // namespace probslam::bindings
