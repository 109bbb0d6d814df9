#pragma once
// A fixed set of worker threads for one multi-threaded call (OccupancyGrid3D::insert_point_cloud).
//
// Every thread is started in the constructor, before the caller changes anything: when the system
// refuses one (std::system_error), the threads already started are stopped and joined and the
// error propagates, so the call raises with its object untouched instead of aborting the process
// (a joinable std::thread destroyed during unwinding calls std::terminate).
#include <atomic>
#include <condition_variable>
#include <cstddef>
#include <cstdint>
#include <exception>
#include <functional>
#include <mutex>
#include <system_error>
#include <thread>
#include <vector>

namespace probslam {

namespace testing {
/// Test hook: after `successes` more worker-thread starts, the next one fails with
/// std::system_error (resource_unavailable_try_again), as when the system refuses a thread
/// (RLIMIT_NPROC does not bind root, so tests inject the failure here). Negative: never fail.
inline std::atomic<int> worker_start_failure_after{-1};
}  // namespace testing

class WorkerPool {
 public:
  /// workers - 1 threads (the calling thread is worker 0). Throws std::system_error, with no
  /// thread left running, when one cannot be started.
  explicit WorkerPool(std::size_t workers) {
    threads_.reserve(workers > 0 ? workers - 1 : 0);  // so that adding a started thread cannot throw
    try {
      for (std::size_t w = 1; w < workers; ++w) threads_.push_back(start([this, w] { serve(w); }));
    } catch (...) {
      stop();
      throw;
    }
  }
  WorkerPool(const WorkerPool&) = delete;
  WorkerPool& operator=(const WorkerPool&) = delete;
  ~WorkerPool() { stop(); }

  std::size_t size() const { return threads_.size() + 1; }

  /// Runs work(w) for every worker w at once (w = 0 on the calling thread) and waits for all;
  /// then rethrows the first exception one of them raised.
  void run(const std::function<void(std::size_t)>& work) {
    {
      std::lock_guard<std::mutex> lock(mutex_);
      job_ = &work;
      pending_ = threads_.size();
      error_ = nullptr;
      ++generation_;
    }
    wake_.notify_all();
    execute(work, 0);
    std::unique_lock<std::mutex> lock(mutex_);
    done_.wait(lock, [this] { return pending_ == 0; });
    job_ = nullptr;
    if (error_) std::rethrow_exception(error_);
  }

 private:
  template <class F>
  static std::thread start(F&& f) {
    int left = testing::worker_start_failure_after.load();
    while (left >= 0 && !testing::worker_start_failure_after.compare_exchange_weak(left, left - 1)) {
    }
    if (left == 0) {
      testing::worker_start_failure_after.store(-1);
      throw std::system_error(std::make_error_code(std::errc::resource_unavailable_try_again),
                              "cannot start a worker thread (test hook)");
    }
    return std::thread(std::forward<F>(f));
  }

  void execute(const std::function<void(std::size_t)>& work, std::size_t w) {
    try {
      work(w);
    } catch (...) {
      std::lock_guard<std::mutex> lock(mutex_);
      if (!error_) error_ = std::current_exception();
    }
  }

  void serve(std::size_t w) {
    std::uint64_t seen = 0;
    for (;;) {
      const std::function<void(std::size_t)>* job;
      {
        std::unique_lock<std::mutex> lock(mutex_);
        wake_.wait(lock, [&] { return quit_ || generation_ != seen; });
        if (quit_) return;
        seen = generation_;
        job = job_;
      }
      execute(*job, w);
      std::lock_guard<std::mutex> lock(mutex_);
      if (--pending_ == 0) done_.notify_one();
    }
  }

  void stop() noexcept {
    {
      std::lock_guard<std::mutex> lock(mutex_);
      quit_ = true;
    }
    wake_.notify_all();
    for (std::thread& t : threads_) t.join();
    threads_.clear();
  }

  std::vector<std::thread> threads_;
  std::mutex mutex_;
  std::condition_variable wake_, done_;
  const std::function<void(std::size_t)>* job_ = nullptr;
  std::uint64_t generation_ = 0;
  std::size_t pending_ = 0;
  bool quit_ = false;
  std::exception_ptr error_;
};

}  // namespace probslam
