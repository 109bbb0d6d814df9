#pragma once
// The laser SLAM classes' stage timers count processor time, not wall time: on a shared machine
// the wall clock also counts the time other processes held the core.
#include <ctime>

namespace probslam {

/// Processor time of this process so far (s): std::clock, which POSIX systems serve from the
/// process's CPU-time clock (all its threads; microsecond steps).
inline double cpu_seconds() { return static_cast<double>(std::clock()) / CLOCKS_PER_SEC; }

/// Adds the processor time of its scope to `total`, however the scope ends (return or throw).
class ScopedCpuTimer {
 public:
  explicit ScopedCpuTimer(double& total) : total_(total), start_(cpu_seconds()) {}
  ~ScopedCpuTimer() { total_ += cpu_seconds() - start_; }
  ScopedCpuTimer(const ScopedCpuTimer&) = delete;
  ScopedCpuTimer& operator=(const ScopedCpuTimer&) = delete;

 private:
  double& total_;
  double start_;
};

}  // namespace probslam
