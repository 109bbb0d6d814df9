#pragma once
// Montemerlo's log(N) FastSLAM map sharing: a persistent (path-copying) treap whose immutable,
// reference-counted nodes are shared between particles, and the per-particle landmark map built
// on two of them.
//
// Persistence: a tree is a handle on a root node. A shared node never changes; an insert, update
// or erase builds new copies of the O(log N) nodes on the path from the root to the changed key
// and points them at the untouched subtrees of the old tree. Copying a handle (resampling a
// particle) copies one pointer. So no change through one handle can ever show through another,
// whatever nodes they share. The exception, invisible from outside: an insert changes in place
// the nodes at the top of its path that this handle alone reaches (a count of one all the way
// from the root, such as the nodes an earlier insert through it copied), as a copy would have
// built them: a particle's several landmark updates of a scan copy their shared top once.
//
// Threads: nodes are immutable once built and their reference counts are atomic, so handles on
// different threads may share nodes; one handle must not be changed by two threads at once.
//
// Balance: a treap whose priorities are a hash of the key. Its shape is the unique one of the
// key set (independent of the order of operations), with expected depth O(log N).
#include <Eigen/Core>

#include <algorithm>
#include <atomic>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <limits>
#include <unordered_set>
#include <utility>
#include <vector>

#include "probslam/fastslam/node_pool.hpp"
#include "probslam/fastslam/node_ref.hpp"

namespace probslam {

class StateWriter;
class StateReader;

/// Tree nodes alive in the process, over every tree (tests and memory reports).
inline ShardedCounter g_persistent_tree_nodes;

/// A persistent ordered map Key -> Value (Key: strict weak order by operator<, priority by
/// KeyHash). Every operation is O(log N) expected and copies only the nodes on one path.
template <class Key, class Value, class KeyHash>
class PersistentTreap {
 public:
  struct Node {
    Key key;
    Value value;
    std::uint64_t priority;
    std::size_t size;  // nodes in this subtree
    NodeRef<Node> left, right;
    mutable std::atomic<std::uint32_t> refs{1};

    Node(const Key& k, const Value& v, std::uint64_t p, NodeRef<Node> l, NodeRef<Node> r)
        : key(k), value(v), priority(p), size(1 + size_of(l) + size_of(r)), left(std::move(l)), right(std::move(r)) {
      g_persistent_tree_nodes.add(1);
    }
    ~Node() { g_persistent_tree_nodes.add(-1); }
    static void* operator new(std::size_t) { return NodePool<Node>::allocate(); }
    static void operator delete(void* p) noexcept { NodePool<Node>::release(p); }
    // Recursion through the children's destructors is as deep as the tree: O(log N).
    static void destroy(const Node* n) { delete n; }
  };
  using Ref = NodeRef<Node>;

  std::size_t size() const { return size_of(root_); }
  bool empty() const { return !root_; }
  const Node* root() const { return root_.get(); }

  const Value* find(const Key& key) const {
    const Node* t = root_.get();
    while (t) {
      if (key < t->key) t = t->left.get();
      else if (t->key < key) t = t->right.get();
      else return &t->value;
    }
    return nullptr;
  }

  /// Inserts key, or replaces its value.
  void insert_or_assign(const Key& key, const Value& value) { insert_owned(root_, key, value, KeyHash()(key)); }

  /// Removes key; false (and nothing copied) if it is absent.
  bool erase(const Key& key) {
    bool found = false;
    Ref r = erase(root_, key, found);
    if (found) root_ = std::move(r);
    return found;
  }

  /// f(key, value) for every key in [lo, hi], in order: O(k + log N).
  template <class F>
  void for_each_in_range(const Key& lo, const Key& hi, F&& f) const {
    visit_range(root_.get(), lo, hi, f);
  }
  template <class F>
  void for_each(F&& f) const {
    visit_all(root_.get(), f);
  }
  /// f(key, value), in order, for every node whose subtree `may_hold(lo, hi)` does not rule out:
  /// lo and hi bound the subtree's keys (exclusive; nullptr: unbounded), and may_hold returns
  /// false only when no key that f wants lies between them. f filters the keys it is given.
  template <class MayHold, class F>
  void for_each_pruned(MayHold&& may_hold, F&& f) const {
    visit_pruned(root_.get(), nullptr, nullptr, may_hold, f);
  }

  /// Adds the nodes of this tree not in `seen` to it; shared subtrees are skipped, so the cost is
  /// that of the nodes new to `seen`. Returns how many were added.
  std::size_t collect_nodes(std::unordered_set<const void*>& seen) const { return collect(root_.get(), seen); }

 private:
  static std::size_t size_of(const Ref& r) { return r ? r->size : 0; }

  static Ref make(const Node& like, Ref l, Ref r) {
    return Ref::adopt(new Node(like.key, like.value, like.priority, std::move(l), std::move(r)));
  }
  // Strict order on (priority, key): the node that wins is nearer the root.
  static bool above(std::uint64_t pa, const Key& ka, const Node& b) {
    return pa > b.priority || (pa == b.priority && ka < b.key);
  }

  // (keys < key, keys > key) of t, which does not hold key.
  static std::pair<Ref, Ref> split(const Ref& t, const Key& key) {
    if (!t) return {};
    if (t->key < key) {
      auto [l, r] = split(t->right, key);
      return {make(*t, t->left, std::move(l)), std::move(r)};
    }
    auto [l, r] = split(t->left, key);
    return {std::move(l), make(*t, std::move(r), t->right)};
  }

  // Every key of a is below every key of b.
  static Ref merge(const Ref& a, const Ref& b) {
    if (!a) return b;
    if (!b) return a;
    if (above(a->priority, a->key, *b)) return make(*a, a->left, merge(a->right, b));
    return make(*b, merge(a, b->left), b->right);
  }

  // insert() into the subtree at `slot`, changing in place the nodes only this path reaches: a
  // node whose count is one below a node reached that way has no other owner (counts are only
  // raised by copying a reference, which needs one). The result is the tree insert() builds.
  static void insert_owned(Ref& slot, const Key& key, const Value& value, std::uint64_t priority) {
    if (!slot || slot->refs.load(std::memory_order_acquire) != 1) {
      slot = insert(slot, key, value, priority);
      return;
    }
    Node& t = const_cast<Node&>(*slot);
    if (!(key < t.key) && !(t.key < key)) {
      t.value = value;  // the same key: the same priority
      return;
    }
    if (above(priority, key, t)) {  // the new node goes here: split (copying) as insert() does
      slot = insert(slot, key, value, priority);
      return;
    }
    insert_owned(key < t.key ? t.left : t.right, key, value, priority);
    t.size = 1 + size_of(t.left) + size_of(t.right);
  }

  // An existing key lies on the search path above every node of lower priority (heap order),
  // so it is met before the new node could be placed.
  static Ref insert(const Ref& t, const Key& key, const Value& value, std::uint64_t priority) {
    if (!t) return Ref::adopt(new Node(key, value, priority, Ref(), Ref()));
    if (!(key < t->key) && !(t->key < key))
      return Ref::adopt(new Node(key, value, priority, t->left, t->right));
    if (above(priority, key, *t)) {
      auto [l, r] = split(t, key);
      return Ref::adopt(new Node(key, value, priority, std::move(l), std::move(r)));
    }
    if (key < t->key) return make(*t, insert(t->left, key, value, priority), t->right);
    return make(*t, t->left, insert(t->right, key, value, priority));
  }

  static Ref erase(const Ref& t, const Key& key, bool& found) {
    if (!t) return Ref();
    if (key < t->key) {
      Ref l = erase(t->left, key, found);
      return found ? make(*t, std::move(l), t->right) : Ref();
    }
    if (t->key < key) {
      Ref r = erase(t->right, key, found);
      return found ? make(*t, t->left, std::move(r)) : Ref();
    }
    found = true;
    return merge(t->left, t->right);
  }

  template <class F>
  static void visit_range(const Node* t, const Key& lo, const Key& hi, F& f) {
    while (t) {
      const bool above_lo = lo < t->key, below_hi = t->key < hi;
      if (above_lo) visit_range(t->left.get(), lo, hi, f);
      if (!(t->key < lo) && !(hi < t->key)) f(t->key, t->value);
      if (!below_hi) return;
      t = t->right.get();  // the right subtree by iteration
    }
  }
  template <class M, class F>
  static void visit_pruned(const Node* t, const Key* lo, const Key* hi, M& may_hold, F& f) {
    while (t && may_hold(lo, hi)) {
      visit_pruned(t->left.get(), lo, &t->key, may_hold, f);
      f(t->key, t->value);
      lo = &t->key;
      t = t->right.get();  // the right subtree by iteration
    }
  }
  template <class F>
  static void visit_all(const Node* t, F& f) {
    while (t) {
      visit_all(t->left.get(), f);
      f(t->key, t->value);
      t = t->right.get();
    }
  }
  static std::size_t collect(const Node* t, std::unordered_set<const void*>& seen) {
    std::size_t n = 0;
    while (t && seen.insert(t).second) {
      ++n;
      n += collect(t->left.get(), seen);
      t = t->right.get();
    }
    return n;
  }

  Ref root_;
};

/// One landmark of a particle's map: a 2-D Gaussian (metres), an existence counter, and the
/// signature's mean and variance when the filter uses signatures.
struct Landmark {
  long id = 0;
  Eigen::Vector2d mean = Eigen::Vector2d::Zero();
  Eigen::Matrix2d cov = Eigen::Matrix2d::Zero();  // kept symmetric to the bit
  double existence = 1.0;
  double signature = 0.0;
  double signature_var = 0.0;
  int sightings = 1;   // scans that saw it (update_unknown; capped at kFastSlamMaxCount)
  long last_seen = 0;  // the particle's scan count (FastSlamParticle::scans) when last seen
};

/// A particle's landmarks, keyed for both queries FastSLAM needs, in two persistent treaps:
///  - spatial: key (cell_y, cell_x, id) of a square grid over the landmark mean -> the landmark.
///    Ordered row by row, so the landmarks of one row of cells [cx0, cx1] are one key range and
///    "within r of (x, y)" is (2r / cell + 2) range queries, each O(k + log N).
///  - by id: id -> its cell, O(log N); with the cell, the spatial lookup is O(log N) too.
/// A second tree keyed by id (rather than one tree keyed by id with a separate spatial index)
/// keeps both lookups O(log N) and both persistent: any per-particle spatial index outside the
/// trees would have to be copied on resampling (O(N)). The price is a second path copy, and
/// only when a landmark changes cell (or is added or removed); a landmark updated within its
/// cell copies one path of the spatial tree only.
class LandmarkMap {
 public:
  /// Cell indices are clamped to +-2^52: far inside int64, and beyond any map (2^52 cells of
  /// 1 um are 4.5e9 m).
  static constexpr double kMaxCellIndex = 4503599627370496.0;

  struct CellKey {
    std::int64_t cy = 0, cx = 0;
    long id = 0;
    bool operator<(const CellKey& o) const {
      if (cy != o.cy) return cy < o.cy;
      if (cx != o.cx) return cx < o.cx;
      return id < o.id;
    }
    bool operator==(const CellKey& o) const { return cy == o.cy && cx == o.cx && id == o.id; }
  };
  struct CellHash {
    std::uint64_t operator()(const CellKey& k) const {
      return mix64(mix64(mix64(static_cast<std::uint64_t>(k.id)) ^ static_cast<std::uint64_t>(k.cx)) ^
                   static_cast<std::uint64_t>(k.cy));
    }
  };
  struct IdHash {
    std::uint64_t operator()(long id) const { return mix64(static_cast<std::uint64_t>(id) ^ 0x5bd1e9955bd1e995ULL); }
  };
  struct Cell {
    std::int64_t cy = 0, cx = 0;
  };
  using SpatialTree = PersistentTreap<CellKey, Landmark, CellHash>;
  using IdTree = PersistentTreap<long, Cell, IdHash>;

  /// cell_size in metres, > 0 (checked by the owner).
  explicit LandmarkMap(double cell_size = 1.0) : cell_(cell_size) {}

  double cell_size() const { return cell_; }
  std::size_t size() const { return ids_.size(); }

  std::int64_t cell_of(double v) const {
    return static_cast<std::int64_t>(std::clamp(std::floor(v / cell_), -kMaxCellIndex, kMaxCellIndex));
  }
  Cell cell_of(const Eigen::Vector2d& p) const { return {cell_of(p.y()), cell_of(p.x())}; }

  /// The landmark with this id, or nullptr. The pointer stays valid while this map (or any copy
  /// sharing the node) is alive and unchanged.
  const Landmark* find(long id) const {
    const Cell* c = ids_.find(id);
    return c ? spatial_.find(CellKey{c->cy, c->cx, id}) : nullptr;
  }

  /// Inserts the landmark, or replaces the one with its id (moving it between cells if needed).
  void put(const Landmark& lm) {
    const Cell c = cell_of(lm.mean);
    const CellKey key{c.cy, c.cx, lm.id};
    if (const Cell* old = ids_.find(lm.id)) {
      if (old->cy == c.cy && old->cx == c.cx) {
        spatial_.insert_or_assign(key, lm);
        return;
      }
      spatial_.erase(CellKey{old->cy, old->cx, lm.id});
    }
    spatial_.insert_or_assign(key, lm);
    ids_.insert_or_assign(lm.id, c);
  }

  bool erase(long id) {
    const Cell* c = ids_.find(id);
    if (!c) return false;
    spatial_.erase(CellKey{c->cy, c->cx, id});
    ids_.erase(id);
    return true;
  }

  /// f(landmark) for every landmark whose mean is within `radius` (m) of `center`. Visits the
  /// rows of cells the disc covers; when there are more rows than landmarks, walks the whole map.
  template <class F>
  void for_each_within(const Eigen::Vector2d& center, double radius, F&& f) const {
    if (ids_.empty() || !(radius >= 0.0)) return;
    const double r2 = radius * radius;
    const auto near = [&](const CellKey&, const Landmark& lm) {
      if ((lm.mean - center).squaredNorm() <= r2) f(lm);
    };
    const double rows = std::floor((center.y() + radius) / cell_) - std::floor((center.y() - radius) / cell_) + 1.0;
    if (!std::isfinite(radius) || !(rows <= static_cast<double>(size()))) {
      spatial_.for_each(near);
      return;
    }
    const std::int64_t cy0 = cell_of(center.y() - radius), cy1 = cell_of(center.y() + radius);
    const std::int64_t cx0 = cell_of(center.x() - radius), cx1 = cell_of(center.x() + radius);
    for (std::int64_t cy = cy0; cy <= cy1; ++cy)
      spatial_.for_each_in_range(CellKey{cy, cx0, std::numeric_limits<long>::min()},
                                 CellKey{cy, cx1, std::numeric_limits<long>::max()}, near);
  }

  /// A disc of for_each_within_any: centre and radius (m).
  struct Disc {
    Eigen::Vector2d center;
    double radius;
  };
  /// f(landmark, i) for every disc i and every landmark whose mean is within discs[i] (what
  /// for_each_within(discs[i].center, discs[i].radius, ...) gives for each i), in one walk of the
  /// tree that skips the subtrees outside every disc's rectangle of cells: the top of the tree,
  /// which each row's range query descends again, is read once. Pairs come in key order, not
  /// disc by disc.
  template <class F>
  void for_each_within_any(const std::vector<Disc>& discs, F&& f) const {
    struct Rect {
      std::int64_t cy0, cy1, cx0, cx1;
      double r2;
    };
    std::vector<Rect> rects(discs.size());
    bool any = false;
    for (std::size_t i = 0; i < discs.size(); ++i) {
      const Disc& d = discs[i];
      Rect& r = rects[i];
      if (!(d.radius >= 0.0)) {  // none: an empty rectangle
        r = {1, 0, 1, 0, -1.0};
        continue;
      }
      r = {cell_of(d.center.y() - d.radius), cell_of(d.center.y() + d.radius), cell_of(d.center.x() - d.radius),
           cell_of(d.center.x() + d.radius), d.radius * d.radius};
      any = true;
    }
    if (ids_.empty() || !any) return;
    constexpr std::int64_t kLow = std::numeric_limits<std::int64_t>::min(), kHigh = std::numeric_limits<std::int64_t>::max();
    // Keys between lo and hi have cells (cy, cx) from lo's to hi's in row-major order.
    const auto may_hold = [&](const CellKey* lo, const CellKey* hi) {
      const std::int64_t ly = lo ? lo->cy : kLow, lx = lo ? lo->cx : kLow;
      const std::int64_t hy = hi ? hi->cy : kHigh, hx = hi ? hi->cx : kHigh;
      for (const Rect& r : rects) {
        if (r.cy1 < ly || r.cy0 > hy) continue;
        if (ly == hy) {
          if (r.cx0 <= hx && r.cx1 >= lx) return true;
          continue;
        }
        // Rows strictly between lo's and hi's hold every column.
        if (std::max(r.cy0, ly + 1) <= std::min(r.cy1, hy - 1)) return true;
        if (r.cy0 <= ly && ly <= r.cy1 && r.cx1 >= lx) return true;  // lo's row, from lo's column on
        if (r.cy0 <= hy && hy <= r.cy1 && r.cx0 <= hx) return true;  // hi's row, up to hi's column
      }
      return false;
    };
    spatial_.for_each_pruned(may_hold, [&](const CellKey& key, const Landmark& lm) {
      for (std::size_t i = 0; i < rects.size(); ++i) {
        const Rect& r = rects[i];
        if (key.cy >= r.cy0 && key.cy <= r.cy1 && key.cx >= r.cx0 && key.cx <= r.cx1 &&
            (lm.mean - discs[i].center).squaredNorm() <= r.r2)
          f(lm, i);
      }
    });
  }

  /// f(landmark) for every landmark, in spatial key order.
  template <class F>
  void for_each(F&& f) const {
    spatial_.for_each([&](const CellKey&, const Landmark& lm) { f(lm); });
  }

  /// Nodes of both trees (what a deep copy of this map would allocate).
  std::size_t num_nodes() const { return spatial_.size() + ids_.size(); }
  /// Adds this map's nodes to `seen`; returns how many were new.
  std::size_t collect_nodes(std::unordered_set<const void*>& seen) const {
    return spatial_.collect_nodes(seen) + ids_.collect_nodes(seen);
  }
  /// The cell size and every landmark. The trees' shapes depend on their key sets alone, so
  /// read_state rebuilds them as they were (in nodes of its own: sharing is not saved).
  void write_state(StateWriter& w) const;
  static LandmarkMap read_state(StateReader& r);
  const SpatialTree& spatial_tree() const { return spatial_; }
  const IdTree& id_tree() const { return ids_; }

 private:
  double cell_;
  SpatialTree spatial_;
  IdTree ids_;
};

}  // namespace probslam
