#pragma once
// The pose graph readers' options from their Python arguments (format, noise, rows), shared by
// the 2-D reader (graph.cpp) and the 3-D one (io.cpp); ValueError naming the argument.
#include <string>

#include "probslam/io/pose_graph_file.hpp"

namespace probslam::bindings {

PoseGraphFormat format_arg(const std::string& format);
PoseGraphReadOptions read_options(const std::string& format, const std::string& noise, const std::string& rows);

}  // namespace probslam::bindings
