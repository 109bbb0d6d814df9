#pragma once
// Argument validation shared by every module: each failure throws std::invalid_argument
// whose message starts with the offending argument's name.
#include <Eigen/Cholesky>
#include <Eigen/Core>
#include <cmath>
#include <stdexcept>
#include <string>

namespace probslam {

/// A file named by an argument does not exist. It is an std::invalid_argument (a missing input
/// is a bad argument, and handlers of that keep working); the bindings raise FileNotFoundError.
class FileNotFound : public std::invalid_argument {
 public:
  using std::invalid_argument::invalid_argument;
};

[[noreturn]] void throw_invalid_argument(const std::string& name, const std::string& what);

inline void require(bool condition, const char* name, const char* what) {
  if (!condition) throw_invalid_argument(name, what);
}

inline void require_finite(double value, const char* name) {
  require(std::isfinite(value), name, "must be finite");
}

inline void require_positive(double value, const char* name) {
  require(std::isfinite(value) && value > 0.0, name, "must be finite and > 0");
}

inline void require_probability(double value, const char* name) {
  require(std::isfinite(value) && value > 0.0 && value < 1.0, name,
          "must be a probability strictly between 0 and 1");
}

template <typename Derived>
void require_all_finite(const Eigen::DenseBase<Derived>& values, const char* name) {
  require(values.allFinite(), name, "must contain only finite values");
}

/// Finite, symmetric up to `symmetry_tolerance` relative to its largest entry, and positive
/// definite (its Cholesky factorisation succeeds).
template <typename Derived>
void require_symmetric_positive_definite(const Eigen::MatrixBase<Derived>& m, const char* name,
                                         double symmetry_tolerance) {
  require_all_finite(m, name);
  require((m - m.transpose()).cwiseAbs().maxCoeff() <= symmetry_tolerance * m.cwiseAbs().maxCoeff(),
          name, "must be symmetric");
  require(Eigen::LLT<typename Derived::PlainObject>(m).info() == Eigen::Success, name,
          "must be positive definite");
}

}  // namespace probslam
