#include "probslam/core/check.hpp"

#include <stdexcept>

namespace probslam {

void throw_invalid_argument(const std::string& name, const std::string& what) {
  throw std::invalid_argument(name + " " + what);
}

}  // namespace probslam
