#pragma once
// What a graph vertex stands for: the 2-D and 3-D graphs keep poses and point landmarks in one
// vertex list (one id space, as g2o files have), told apart by this.

namespace probslam {

enum class VertexKind { kPose, kPoint };

}  // namespace probslam
