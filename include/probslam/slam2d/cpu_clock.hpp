#pragma once
// The laser SLAM classes' stage timers count processor time, not wall time: on a shared machine
// the wall clock also counts the time other processes held the core.
#include <ctime>

namespace probslam {

/// Processor time of this process so far (s): std::clock, which POSIX systems serve from the
/// process's CPU-time clock (all its threads; microsecond steps).
inline double cpu_seconds() { return static_cast<double>(std::clock()) / CLOCKS_PER_SEC; }

}  // namespace probslam
