#pragma once
// EKF SLAM with unknown correspondences kept open over several scans: a beam of EkfSlam filters,
// each one assignment history (track-splitting multiple-hypothesis association). Where
// Table 10.2 commits to the most likely pairing of every scan, a pairing that later scans
// contradict (a lost heading re-seeing one landmark, a first sighting that was an outlier) is
// overtaken by the branch that did not make it.
#include <Eigen/Core>
#include <memory>
#include <string>
#include <vector>

#include "probslam/core/object_mutex.hpp"
#include "probslam/core/types.hpp"
#include "probslam/ekf/ekf_slam.hpp"

namespace probslam {

/// Costs are -2 log-likelihoods relative to a pairing with zero innovation and S = Q, so they
/// read as NIS values: a pairing costs NIS + log det(S Q^-1) (Q's bearing variance plus the
/// bearing offset's, when there is one).
struct MultiHypothesisOptions {
  int max_hypotheses = 10;          // filters kept after each scan (the beam)
  int max_children = 4;             // assignments of one scan tried per filter, cheapest first
  // The three below depend on the measurement's dimension (2, or 3 with signatures): 0 (the
  // default) stands for the chi-square quantile of its kDefault*Probability below for that
  // many degrees of freedom, resolved when a filter takes the options.
  double gate = 0.0;                // NIS gate of a pairing candidate
  double new_landmark_cost = 0.0;   // a measurement starting a landmark
  double clutter_cost = 0.0;        // a measurement dropped as a false detection or outlier
  double prune_margin = 40.0;       // filters costing more than the best plus this are dropped
  // Missed detections (0: off): a landmark of a filter within sensor_range (m) and sensor_fov
  // (rad, centred ahead) of its pose before the scan costs -2 ln P_D when a measurement of the
  // scan goes to it and -2 ln(1 - P_D) when none does.
  double detection_probability = 0.0;
  double sensor_range = 0.0;
  double sensor_fov = 0.0;
  // A bearing offset b shared by the measurements of one scan (0: off): bearing = atan2(dy, dx) -
  // theta - b + noise, a camera that misreads a frame as a whole. b is stationary with standard
  // deviation bearing_offset_sigma (rad) and an AR(1) from scan to scan (b' = rho b + w,
  // rho = bearing_offset_correlation in [0, 1); 0: afresh per scan). Each filter carries b's
  // mean, variance and covariance with its state: a scan's sightings are judged by their joint
  // geometry and by the offset the earlier scans left (measurement_noise is then the part not shared).
  double bearing_offset_sigma = 0.0;
  double bearing_offset_correlation = 0.0;

  /// The chi-square probabilities behind the defaults of gate, new_landmark_cost, clutter_cost.
  static constexpr double kDefaultGateProbability = 0.999;
  static constexpr double kDefaultNewLandmarkProbability = 1.0 - 1e-6;
  static constexpr double kDefaultClutterProbability = 1.0 - 4.5e-5;

  /// std::invalid_argument naming the first field out of its range.
  void validate() const;
  /// These options with the 0 costs replaced by their quantiles for `dof` measurement dimensions.
  MultiHypothesisOptions resolved(int dof) const;

  /// The fields in the order the state files hold them (core/options_description.hpp).
  template <class V>
  static void describe(V& v) {
    using O = MultiHypothesisOptions;
    v("max_hypotheses", &O::max_hypotheses, "", "filters kept after each scan, the beam, in [1, 1000]");
    v("max_children", &O::max_children, "", "assignments of one scan tried per filter, cheapest first, in [1, 100]");
    v("gate", &O::gate, "NIS", "gate of a pairing candidate (0: the chi-square quantile 0.999 of the measurement's dimension)");
    v("new_landmark_cost", &O::new_landmark_cost, "NIS", "cost of a measurement starting a landmark (0: the quantile 1 - 1e-6)");
    v("clutter_cost", &O::clutter_cost, "NIS", "cost of a measurement dropped as clutter (0: the quantile 1 - 4.5e-5)");
    v("prune_margin", &O::prune_margin, "NIS", "filters costing more than the best plus this are dropped");
    v("detection_probability", &O::detection_probability, "", "P_D of a landmark inside the sensor's field, in [0, 1) (0: off)");
    v("sensor_range", &O::sensor_range, "m", "range of the sensor's field (with P_D > 0)");
    v("sensor_fov", &O::sensor_fov, "rad", "full opening angle of the sensor's field, centred ahead (with P_D > 0)");
    v("bearing_offset_sigma", &O::bearing_offset_sigma, "rad", "std of a bearing offset shared by a scan's measurements, in [0, pi] (0: off)");
    v("bearing_offset_correlation", &O::bearing_offset_correlation, "", "its AR(1) correlation from scan to scan, in [0, 1)");
  }
};

/// Reliability limits: the beam and the children per filter, each a full copy of a filter.
inline constexpr int kMhtMaxHypotheses = 1000;
inline constexpr int kMhtMaxChildren = 100;
/// Costs and the prune margin, in NIS units: chi-square quantiles of any probability a double
/// resolves are far below this.
inline constexpr double kMhtMaxCost = 1e6;
/// Costs closer than this (NIS units) rank as equal when the beam is chosen: far above the
/// rounding of sums of costs below kMhtMaxCost, far below any difference a decision makes.
inline constexpr double kMhtCostResolution = 1e-6;
/// Bytes of covariance the children of one scan may hold together (beam x children x state^2).
inline constexpr double kMhtMaxBranchBytes = 4.0 * (1 << 30);


/// Every call validates all input first and leaves the beam unchanged when it throws.
class MultiHypothesisEkfSlam {
 public:
  /// Lock it around every call when several threads share this object (core/object_mutex.hpp).
  std::mutex& mutex() const noexcept { return mutex_.get(); }

  /// Starts from one filter (copied); every option must be positive, the costs finite.
  MultiHypothesisEkfSlam(const EkfSlam& initial, const MultiHypothesisOptions& options);

  /// Table 10.1 lines 2-5 on every filter (see EkfSlam::predict).
  void predict(double v, double w, double dt);
  void predict(double v, double w, double dt, const Eigen::MatrixXd& noise);

  /// One scan z (k x 2, or k x 3 with signatures). Each filter branches into its cheapest
  /// assignments (every measurement to a gated landmark, a new landmark or clutter; a landmark
  /// takes one measurement per scan), applied one measurement after another; the cheapest
  /// max_hypotheses children within prune_margin of the best survive. Returns the best
  /// filter's landmark id per measurement, -1 for clutter.
  std::vector<long> update(const Eigen::Ref<const RowMatrixXd>& z);

  const EkfSlam& best() const { return beam_.front().filter; }
  int num_hypotheses() const { return static_cast<int>(beam_.size()); }
  /// Cost of each filter above the best's, ascending (the first is 0).
  std::vector<double> costs() const;
  /// The best filter's whole cost: the sum over its scans of pairing, new-landmark and clutter costs.
  double total_cost() const { return offset_ + beam_.front().cost; }
  /// The best filter's assignment of every scan so far: landmark id per measurement, -1 clutter.
  std::vector<std::vector<long>> history() const;
  const MultiHypothesisOptions& options() const { return options_; }

  /// Saves the beam (every filter, its cost, next id, bearing offset and assignment history,
  /// the histories' shared prefixes kept shared) bit for bit (docs/file_format.md).
  static constexpr const char* kStateTag = "MultiHypothesisEkfSlam";
  void save(const std::string& path) const;
  static MultiHypothesisEkfSlam load(const std::string& path);
  void write_state(StateWriter& w) const;
  static MultiHypothesisEkfSlam read_state(StateReader& r);

 private:
  struct HistoryNode {
    std::shared_ptr<const HistoryNode> parent;
    std::vector<long> ids;
  };
  // The bearing offset b: its mean, variance and covariance with the filter's state (n,), whose
  // heading is theta, or theta + b while a scan is taken (see branch()).
  struct ScanOffset {
    double mean = 0.0;
    double var = 0.0;
    Eigen::VectorXd cov;
  };
  struct Hypothesis {
    EkfSlam filter;
    double cost;
    long next_id;
    std::shared_ptr<const HistoryNode> history;
    ScanOffset offset;  // unused when bearing_offset_sigma is 0
  };
  void branch(const Hypothesis& parent, const Eigen::Ref<const RowMatrixXd>& z, std::vector<Hypothesis>& out) const;
  /// Conditions the offset on measurement z of landmark `id`, as the update the filter is about to make.
  static void condition_offset(const EkfSlam& f, const Eigen::VectorXd& z, long id, ScanOffset& b);
  /// Extends the offset's covariance by the landmark that z is about to start.
  static void extend_offset(const EkfSlam& f, const Eigen::VectorXd& z, ScanOffset& b);
  /// Moves the heading by +b (sign 1, to theta + b) or -b (sign -1, back to theta), the
  /// covariances with it: the linear map u = s + sign e_theta b of the joint Gaussian.
  static void shift_heading(EkfSlam& f, ScanOffset& b, double sign);
  bool has_offset() const { return options_.bearing_offset_sigma > 0.0; }

  MultiHypothesisOptions options_;
  std::vector<Hypothesis> beam_;  // best first
  double log_det_q_ = 0.0;        // log det(2 pi Q)
  double offset_ = 0.0;           // cost subtracted from the beam so far
  ObjectMutex mutex_;
};

}  // namespace probslam
