#pragma once
// Allocation of the particle filters' small immutable nodes (persistent landmark trees, pose
// paths), and a counter of live nodes that threads update without sharing a cache line.
//
// A filter step frees and allocates thousands of nodes of one size (the path copies of an
// update, the maps that resampling drops). glibc's allocator spends a quarter of a Victoria Park
// run on them (its small caches hold 7 blocks per size), and its arenas lock when one thread
// frees a block another allocated. A free list per thread and node type serves them instead.
#include <atomic>
#include <cstddef>
#include <new>

namespace probslam {

#if defined(__SANITIZE_ADDRESS__)
#define PROBSLAM_NODE_POOL_ENABLED 0  // AddressSanitizer must see every free, to catch a use after it
#elif defined(__has_feature)
#if __has_feature(address_sanitizer)
#define PROBSLAM_NODE_POOL_ENABLED 0
#endif
#endif
#ifndef PROBSLAM_NODE_POOL_ENABLED
#define PROBSLAM_NODE_POOL_ENABLED 1
#endif

/// Per-thread free lists of blocks of sizeof(T). A block freed by one thread joins that thread's
/// list, whichever thread allocated it; each list keeps at most kMaxCached blocks and returns
/// the rest (and all of them when the thread ends) to the system allocator.
template <class T>
class NodePool {
 public:
  static void* allocate() {
#if PROBSLAM_NODE_POOL_ENABLED
    List& l = local();
    if (Free* f = l.head) {
      l.head = f->next;
      --l.size;
      return f;
    }
#endif
    return ::operator new(sizeof(T));
  }

  static void release(void* p) noexcept {
#if PROBSLAM_NODE_POOL_ENABLED
    List& l = local();
    if (l.size < kMaxCached) {
      l.head = ::new (p) Free{l.head};
      ++l.size;
      return;
    }
#endif
    ::operator delete(p);
  }

 private:
  // About one filter step's churn (100 particles x tens of path copies), half a megabyte per
  // thread and type: enough to serve the steady state from the list, too small to hoard a large
  // freed map. With 65536 the list kept the scattered nodes of a freed 10 000-landmark map, and
  // a later small filter, its nodes spread over them, ran 55% slower (0.84 s against 0.54 s).
  static constexpr std::size_t kMaxCached = 4096;
  struct Free {
    Free* next;
  };
  static_assert(sizeof(T) >= sizeof(Free), "a node must hold a free-list link");
  static_assert(alignof(T) <= __STDCPP_DEFAULT_NEW_ALIGNMENT__, "operator new's alignment must suit the node");
  struct List {
    Free* head = nullptr;
    std::size_t size = 0;
    ~List() {
      while (head) {
        Free* next = head->next;
        ::operator delete(head);
        head = next;
      }
      size = kMaxCached;  // a node freed later on this thread (a static's) goes straight back
    }
  };
  static List& local() {
    thread_local List list;
    return list;
  }
};

/// A count that many threads change often and few read: one cache line per thread slot, summed
/// when read (exact when no thread is changing it).
class ShardedCounter {
 public:
  void add(long delta) noexcept { slots_[slot()].value.fetch_add(delta, std::memory_order_relaxed); }
  long load() const noexcept {
    long sum = 0;
    for (const Slot& s : slots_) sum += s.value.load(std::memory_order_relaxed);
    return sum;
  }

 private:
  static constexpr std::size_t kSlots = 64;
  struct alignas(64) Slot {
    std::atomic<long> value{0};
  };
  static std::size_t slot() noexcept {
    static std::atomic<std::size_t> next{0};
    thread_local const std::size_t mine = next.fetch_add(1, std::memory_order_relaxed) % kSlots;
    return mine;
  }
  Slot slots_[kSlots];
};

}  // namespace probslam
