#include "probslam/grid/map_occupancy_mapping.hpp"

#include <cmath>
#include <limits>
#include <utility>

#include "probslam/core/check.hpp"
#include "probslam/grid/log_odds.hpp"

namespace probslam {
namespace {

// Shapes and values shared by both entry points; returns the per-cell l0 (row-major).
std::vector<double> check_inputs(int width, int height, const Eigen::Ref<const Poses2>& poses,
                                 const Eigen::Ref<const RowMatrixXd>& ranges,
                                 const Eigen::Ref<const RowMatrixXd>& beam_angles,
                                 const Eigen::Ref<const RowMatrixXd>& prior) {
  require(ranges.rows() == poses.rows(), "scans", "must have one row of ranges per pose");
  require(ranges.cols() > 0, "scans", "must hold at least one reading per pose");
  require(beam_angles.rows() == 1 || beam_angles.rows() == ranges.rows(), "beam_angles",
          "must have one row, or one row per pose");
  require(beam_angles.cols() == ranges.cols(), "beam_angles", "must have one angle per reading of a scan");
  require_all_finite(poses, "poses");
  require_all_finite(beam_angles, "beam_angles");
  for (Eigen::Index t = 0; t < ranges.rows(); ++t) require_valid_ranges(ranges.row(t).transpose(), "scans");
  require(prior.rows() == height && prior.cols() == width, "prior", "must have the grid's shape (height, width)");
  std::vector<double> l0(static_cast<std::size_t>(width) * height);
  for (int r = 0; r < height; ++r)
    for (int c = 0; c < width; ++c) {
      const double p = prior(r, c);
      require(p > 0.0 && p < 1.0, "prior", "must hold probabilities strictly between 0 and 1");
      l0[static_cast<std::size_t>(r) * width + c] = logit(p);
    }
  return l0;
}

double beam_angle(const Eigen::Ref<const RowMatrixXd>& beam_angles, Eigen::Index t, Eigen::Index b) {
  return beam_angles(beam_angles.rows() == 1 ? 0 : t, b);
}

// Every reading's footprint within kMaxFootprintVisits, before any is cast.
void check_footprints(const GridLattice2D& lattice, int width, int height, const Eigen::Ref<const Poses2>& poses,
                      const Eigen::Ref<const RowMatrixXd>& beam_angles, Eigen::Index beams,
                      const BeamGeometry& geometry) {
  double visits = 0.0;
  for (Eigen::Index t = 0; t < poses.rows(); ++t)
    for (Eigen::Index b = 0; b < beams; ++b)
      visits += beam_footprint_visits(lattice, width, height, poses.row(t).transpose(), beam_angle(beam_angles, t, b),
                                      geometry);
  require_footprint_budget(visits, "scans");
}

// Eq. 9.24 from scratch: every reading's expected range cast on `map`.
double log_posterior(const BinaryMap2D& map, const Eigen::Ref<const Poses2>& poses,
                     const Eigen::Ref<const RowMatrixXd>& ranges, const Eigen::Ref<const RowMatrixXd>& beam_angles,
                     const BeamSensorModel& model, const std::vector<double>& l0) {
  double sum = 0.0;
  for (Eigen::Index t = 0; t < ranges.rows(); ++t) {
    const Eigen::Vector3d pose = poses.row(t).transpose();
    for (Eigen::Index b = 0; b < ranges.cols(); ++b)
      sum += model.mixture().log_probability(ranges(t, b),
                                             expected_range(map, pose, beam_angle(beam_angles, t, b), model.geometry()));
  }
  for (std::size_t c = 0; c < l0.size(); ++c)
    if (map.occupied(c)) sum += l0[c];
  return sum;
}

// The readings, their footprints and the inverted index of Table 9.3's incremental scorer.
// Reading m's footprint is cells[off[m] .. off[m + 1]) by increasing return range, with the
// log-likelihood of m if that cell were the first occupied one in log_p; log_p_none[m] is its
// log-likelihood when no footprint cell is occupied (z* = max_range).
struct FootprintIndex {
  std::vector<std::size_t> off;
  std::vector<std::int32_t> cells;
  std::vector<double> log_p;
  std::vector<double> log_p_none;
  // Cell c's entries are entries[cell_off[c] .. cell_off[c + 1]): (reading, position in its footprint).
  struct Entry {
    std::int32_t reading, pos;
  };
  std::vector<std::size_t> cell_off;
  std::vector<Entry> entries;
};

FootprintIndex build_index(const OccupancyGrid2D& grid, const Eigen::Ref<const Poses2>& poses,
                           const Eigen::Ref<const RowMatrixXd>& ranges, const Eigen::Ref<const RowMatrixXd>& beam_angles,
                           const BeamSensorModel& model) {
  FootprintIndex ix;
  const std::size_t n_readings = static_cast<std::size_t>(ranges.rows()) * ranges.cols();
  require(n_readings < static_cast<std::size_t>(std::numeric_limits<std::int32_t>::max()), "scans",
          "must hold fewer than 2^31 readings");
  ix.off.reserve(n_readings + 1);
  ix.off.push_back(0);
  ix.log_p_none.reserve(n_readings);
  std::vector<FootprintCell> fp;
  const BeamMixture& mix = model.mixture();
  for (Eigen::Index t = 0; t < ranges.rows(); ++t) {
    const Eigen::Vector3d pose = poses.row(t).transpose();
    for (Eigen::Index b = 0; b < ranges.cols(); ++b) {
      const double z = ranges(t, b);
      beam_footprint(grid.lattice(), grid.width(), grid.height(), pose, beam_angle(beam_angles, t, b),
                     model.geometry(), fp);
      for (const FootprintCell& f : fp) {
        ix.cells.push_back(f.cell);
        ix.log_p.push_back(mix.log_probability(z, f.range));
      }
      ix.off.push_back(ix.cells.size());
      ix.log_p_none.push_back(mix.log_probability(z, mix.max_range));
    }
  }
  const std::size_t n_cells = static_cast<std::size_t>(grid.width()) * grid.height();
  ix.cell_off.assign(n_cells + 1, 0);
  for (const std::int32_t c : ix.cells) ++ix.cell_off[static_cast<std::size_t>(c) + 1];
  for (std::size_t c = 0; c < n_cells; ++c) ix.cell_off[c + 1] += ix.cell_off[c];
  ix.entries.resize(ix.cells.size());
  std::vector<std::size_t> fill(ix.cell_off.begin(), ix.cell_off.end() - 1);
  for (std::size_t m = 0; m + 1 < ix.off.size(); ++m)
    for (std::size_t k = ix.off[m]; k < ix.off[m + 1]; ++k)
      ix.entries[fill[static_cast<std::size_t>(ix.cells[k])]++] = {static_cast<std::int32_t>(m),
                                                                   static_cast<std::int32_t>(k - ix.off[m])};
  return ix;
}

// The incremental scorer: each reading's first occupied footprint position and log-likelihood.
class IncrementalScorer {
 public:
  static constexpr std::size_t kInterruptEvery = 4096;  // a few milliseconds of flips
  IncrementalScorer(const FootprintIndex& ix, std::vector<std::uint8_t>& occupied, const std::vector<double>& l0)
      : ix_(ix), occ_(occupied), l0_(l0) {
    const std::size_t n = ix.log_p_none.size();
    first_.resize(n);
    score_.resize(n);
    for (std::size_t m = 0; m < n; ++m) rescore(m);
  }
  // Eq. 9.24 as the sum of the current per-reading scores and the prior of occupied cells.
  double objective() const {
    double sum = 0.0;
    for (const double s : score_) sum += s;
    for (std::size_t c = 0; c < occ_.size(); ++c)
      if (occ_[c]) sum += l0_[c];
    return sum;
  }
  // Table 9.3 line 5 for cell c: the change of eq. 9.24 if it were flipped; the readings it
  // changes are kept until commit().
  double delta(std::size_t c) {
    pending_.clear();
    const bool was = occ_[c] != 0;
    double d = was ? -l0_[c] : l0_[c];
    for (std::size_t e = ix_.cell_off[c]; e < ix_.cell_off[c + 1]; ++e) {
      const auto [m, pos] = ix_.entries[e];
      const std::size_t begin = ix_.off[m], len = ix_.off[m + 1] - begin;
      std::int32_t new_first;
      if (!was) {
        if (pos >= first_[m]) continue;  // a nearer cell already returns
        new_first = pos;
      } else {
        if (pos != first_[m]) continue;  // not the return cell: nothing changes
        std::size_t k = static_cast<std::size_t>(pos) + 1;
        while (k < len && !occ_[static_cast<std::size_t>(ix_.cells[begin + k])]) ++k;
        new_first = static_cast<std::int32_t>(k);
      }
      const double s = score_at(m, new_first);
      d += s - score_[m];
      pending_.push_back({m, new_first, s});
    }
    return d;
  }
  void commit(std::size_t c) {
    occ_[c] = !occ_[c];
    for (const Pending& p : pending_) {
      first_[p.reading] = p.first;
      score_[p.reading] = p.score;
    }
  }

 private:
  struct Pending {
    std::int32_t reading, first;
    double score;
  };
  double score_at(std::size_t m, std::int32_t first) const {
    const std::size_t begin = ix_.off[m], len = ix_.off[m + 1] - begin;
    return static_cast<std::size_t>(first) < len ? ix_.log_p[begin + first] : ix_.log_p_none[m];
  }
  void rescore(std::size_t m) {
    const std::size_t begin = ix_.off[m], len = ix_.off[m + 1] - begin;
    std::size_t k = 0;
    while (k < len && !occ_[static_cast<std::size_t>(ix_.cells[begin + k])]) ++k;
    first_[m] = static_cast<std::int32_t>(k);
    score_[m] = score_at(m, first_[m]);
  }

  const FootprintIndex& ix_;
  std::vector<std::uint8_t>& occ_;
  const std::vector<double>& l0_;
  std::vector<std::int32_t> first_;
  std::vector<double> score_;
  std::vector<Pending> pending_;
};

// The literal scorer: eq. 9.24 from scratch for the flipped map.
class FullScorer {
 public:
  static constexpr std::size_t kInterruptEvery = 1;  // each flip casts every reading again
  FullScorer(const OccupancyGrid2D& grid, std::vector<std::uint8_t>& occupied, const Eigen::Ref<const Poses2>& poses,
             const Eigen::Ref<const RowMatrixXd>& ranges, const Eigen::Ref<const RowMatrixXd>& beam_angles,
             const BeamSensorModel& model, const std::vector<double>& l0)
      : map_(grid, occupied), occ_(occupied), poses_(poses), ranges_(ranges), angles_(beam_angles), model_(model),
        l0_(l0) {
    current_ = evaluate();
  }
  double objective() const { return current_; }
  double delta(std::size_t c) {
    map_.set(c, !occ_[c]);
    candidate_ = evaluate();
    map_.set(c, occ_[c] != 0);
    return candidate_ - current_;
  }
  void commit(std::size_t c) {
    occ_[c] = !occ_[c];
    map_.set(c, occ_[c] != 0);
    current_ = candidate_;
  }

 private:
  double evaluate() const { return log_posterior(map_, poses_, ranges_, angles_, model_, l0_); }

  BinaryMap2D map_;
  std::vector<std::uint8_t>& occ_;
  const Eigen::Ref<const Poses2>& poses_;
  const Eigen::Ref<const RowMatrixXd>& ranges_;
  const Eigen::Ref<const RowMatrixXd>& angles_;
  const BeamSensorModel& model_;
  const std::vector<double>& l0_;
  double current_ = 0.0, candidate_ = 0.0;
};

// Table 9.3 lines 3-7 with either scorer over the cells of the perceptual field.
template <class Scorer>
void climb(Scorer& scorer, const std::vector<std::int32_t>& field, const std::vector<double>& l0,
           const MapMappingOptions& options, MapMappingResult& result) {
  double objective = scorer.objective();
  bool stopped = false;
  while (!stopped && result.sweeps < options.max_sweeps) {
    ++result.sweeps;
    bool flipped = false;
    for (const std::int32_t c : field) {
      if (options.max_evaluations && result.evaluations >= options.max_evaluations) {
        stopped = true;
        break;
      }
      if (options.interrupt && result.evaluations % Scorer::kInterruptEvery == 0) options.interrupt();
      const double d = scorer.delta(static_cast<std::size_t>(c));  // line 5
      ++result.evaluations;
      if (!(d > MapMappingOptions::kMinGain)) continue;
      scorer.commit(static_cast<std::size_t>(c));
      objective += d;
      ++result.flips;
      flipped = true;
      if (options.record_trace) {
        result.trace_cells.push_back(c);
        result.trace_objective.push_back(objective);
      }
    }
    if (!stopped && !flipped) {
      result.converged = true;
      break;
    }
  }
  result.objective = objective;
  if (!options.sensitivity) return;
  // Fig. 9.8d: each cell flipped alone; outside the field only its prior term changes.
  result.sensitivity.assign(l0.size(), 0.0);
  for (std::size_t c = 0; c < l0.size(); ++c) result.sensitivity[c] = -std::fabs(l0[c]);
  for (std::size_t k = 0; k < field.size(); ++k) {
    if (options.interrupt && k % Scorer::kInterruptEvery == 0) options.interrupt();
    result.sensitivity[static_cast<std::size_t>(field[k])] = scorer.delta(static_cast<std::size_t>(field[k]));
  }
}

}  // namespace

void MapMappingOptions::validate() const { require(max_sweeps >= 1, "max_sweeps", "must be >= 1"); }

MapMappingResult map_occupancy_grid_mapping(const OccupancyGrid2D& geometry, const Eigen::Ref<const Poses2>& poses,
                                            const Eigen::Ref<const RowMatrixXd>& ranges,
                                            const Eigen::Ref<const RowMatrixXd>& beam_angles,
                                            const BeamSensorModel& model, const Eigen::Ref<const RowMatrixXd>& prior,
                                            const MapMappingOptions& options) {
  options.validate();
  const std::vector<double> l0 = check_inputs(geometry.width(), geometry.height(), poses, ranges, beam_angles, prior);
  require(model.mixture().z_rand > 0.0, "z_rand",
          "must be > 0 for MAP mapping: a map that leaves a reading unexplained would score -inf");
  require(model.mixture().z_max > 0.0, "z_max",
          "must be > 0 for MAP mapping: a max reading would score -inf where a cell returns");
  check_footprints(geometry.lattice(), geometry.width(), geometry.height(), poses, beam_angles, ranges.cols(),
                   model.geometry());
  const FootprintIndex ix = build_index(geometry, poses, ranges, beam_angles, model);

  MapMappingResult result;
  result.readings = ix.log_p_none.size();
  result.index_entries = ix.entries.size();
  std::vector<std::int32_t>& field = result.field;  // Table 9.3 line 4, restricted to cells some reading sees
  for (std::size_t c = 0; c + 1 < ix.cell_off.size(); ++c)
    if (ix.cell_off[c + 1] > ix.cell_off[c]) field.push_back(static_cast<std::int32_t>(c));
  result.field_cells = field.size();
  // Line 2: the all-free map; a cell no reading sees only has its prior, maximised at once.
  result.occupied.assign(l0.size(), 0);
  for (std::size_t c = 0; c < l0.size(); ++c)
    if (ix.cell_off[c + 1] == ix.cell_off[c] && l0[c] > 0.0) result.occupied[c] = 1;
  if (options.scoring == FlipScoring::kIncremental) {
    IncrementalScorer scorer(ix, result.occupied, l0);
    climb(scorer, field, l0, options, result);
  } else {
    FullScorer scorer(geometry, result.occupied, poses, ranges, beam_angles, model, l0);
    climb(scorer, field, l0, options, result);
  }
  return result;
}

double map_log_posterior(const BinaryMap2D& map, const Eigen::Ref<const Poses2>& poses,
                         const Eigen::Ref<const RowMatrixXd>& ranges, const Eigen::Ref<const RowMatrixXd>& beam_angles,
                         const BeamSensorModel& model, const Eigen::Ref<const RowMatrixXd>& prior) {
  const std::vector<double> l0 = check_inputs(map.width(), map.height(), poses, ranges, beam_angles, prior);
  check_footprints(map.lattice(), map.width(), map.height(), poses, beam_angles, ranges.cols(), model.geometry());
  return log_posterior(map, poses, ranges, beam_angles, model, l0);
}

}  // namespace probslam
