#pragma once
// A fixed set of worker threads for one multi-threaded call (OccupancyGrid3D::insert_point_cloud,
// the particle filters' per-particle work).
//
// The filters hand out many short jobs (tens of microseconds: one step of 100 particles), where a
// sleeping thread's wake-up (a futex round trip, 10-50 us) costs as much as the job. So a worker
// that has finished spins for a short while (kSpinBudget) on the job counter before it sleeps,
// and the caller spins the same way on the workers' completion.
//
// Every thread is started in the constructor, before the caller changes anything: when the system
// refuses one (std::system_error), the threads already started are stopped and joined and the
// error propagates, so the call raises with its object untouched instead of aborting the process
// (a joinable std::thread destroyed during unwinding calls std::terminate).
#include <atomic>
#include <chrono>
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
      pending_.store(threads_.size(), std::memory_order_relaxed);
      error_ = nullptr;
      generation_.fetch_add(1, std::memory_order_release);  // publishes job_ to spinning workers
    }
    wake_.notify_all();
    execute(work, 0);
    if (!spin_until([this] { return pending_.load(std::memory_order_acquire) == 0; })) {
      std::unique_lock<std::mutex> lock(mutex_);
      done_.wait(lock, [this] { return pending_.load(std::memory_order_acquire) == 0; });
    }
    std::lock_guard<std::mutex> lock(mutex_);
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

  /// Tells the core this is a busy-wait (x86's pause: the sibling hyperthread gets the pipeline).
  static void cpu_relax() noexcept {
#if defined(__x86_64__) || defined(__i386__)
    __builtin_ia32_pause();
#endif
  }

  /// Polls `ready` for up to kSpinBudget; true when it held. After the first kPausePolls polls
  /// it yields between polls: on a machine with more runnable threads than cores the
  /// thread it waits for may need this core.
  template <class Ready>
  static bool spin_until(Ready&& ready) {
    for (int i = 0; i < kPausePolls; ++i) {
      if (ready()) return true;
      cpu_relax();
    }
    const auto until = std::chrono::steady_clock::now() + kSpinBudget;
    for (;;) {
      for (int i = 0; i < kYieldsPerClockRead; ++i) {
        if (ready()) return true;
        std::this_thread::yield();
      }
      if (std::chrono::steady_clock::now() >= until) return ready();
    }
  }

  void serve(std::size_t w) {
    std::uint64_t seen = 0;
    for (;;) {
      const bool fresh = spin_until([&] {
        return generation_.load(std::memory_order_acquire) != seen || quit_.load(std::memory_order_acquire);
      });
      const std::function<void(std::size_t)>* job;
      {
        std::unique_lock<std::mutex> lock(mutex_);
        if (!fresh) {
          wake_.wait(lock, [&] {
            return quit_.load(std::memory_order_relaxed) || generation_.load(std::memory_order_relaxed) != seen;
          });
        }
        if (quit_.load(std::memory_order_relaxed)) return;
        seen = generation_.load(std::memory_order_relaxed);
        job = job_;
      }
      execute(*job, w);
      if (pending_.fetch_sub(1, std::memory_order_acq_rel) == 1) {
        std::lock_guard<std::mutex> lock(mutex_);  // so a caller between its check and its wait hears it
        done_.notify_one();
      }
    }
  }

  void stop() noexcept {
    {
      std::lock_guard<std::mutex> lock(mutex_);
      quit_.store(true, std::memory_order_release);
    }
    wake_.notify_all();
    for (std::thread& t : threads_) t.join();
    threads_.clear();
  }

  // How long an idle worker (or the waiting caller) polls before it sleeps: longer than the gap
  // between two calls of a filter's step loop in Python (10-100 us), short enough that an idle
  // pool gives its core back at once to anyone who needs it.
  static constexpr std::chrono::microseconds kSpinBudget{200};
  static constexpr int kPausePolls = 64;          // about a microsecond of pause polls first
  static constexpr int kYieldsPerClockRead = 8;

  std::vector<std::thread> threads_;
  std::mutex mutex_;
  std::condition_variable wake_, done_;
  const std::function<void(std::size_t)>* job_ = nullptr;  // written under mutex_, before generation_
  std::atomic<std::uint64_t> generation_{0};
  std::atomic<std::size_t> pending_{0};
  std::atomic<bool> quit_{false};
  std::exception_ptr error_;
};

}  // namespace probslam
