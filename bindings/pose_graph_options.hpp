#pragma once
// The pose graph readers' options from their Python arguments (format, noise, rows, equivalences), shared by
// the 2-D reader (graph.cpp) and the 3-D one (io.cpp); ValueError naming the argument.
#include <string>

#include "probslam/io/pose_graph_file.hpp"

namespace probslam::bindings {

PoseGraphFormat format_arg(const std::string& format);
/// equivalences: "merge" or "ignore" (TORO EQUIV records; only the 2-D reader reads them).
PoseGraphReadOptions read_options(const std::string& format, const std::string& noise, const std::string& rows,
                                  const std::string& equivalences = "merge");

}  // namespace probslam::bindings
