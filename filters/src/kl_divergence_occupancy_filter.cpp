// SPDX-License-Identifier: BSD-3-Clause
#include <planar_grid/core/exceptions.h>
#include <planar_grid/filters/kl_divergence_occupancy_filter.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <string>

namespace planar_grid {

// The non-template free functions are compiled whatever PCL_NO_PRECOMPILE says.

OccupancyUpdateRule
occupancyUpdateRuleFromString(const std::string& name)
{
  if (name == "kl_divergence")
    return OccupancyUpdateRule::KL_DIVERGENCE;
  if (name == "log_odds")
    return OccupancyUpdateRule::LOG_ODDS;
  throw Exception("Unknown occupancy update rule '" + name
                  + "' (known: kl_divergence, log_odds)");
}

std::string
toString(OccupancyUpdateRule rule)
{
  switch (rule) {
    case OccupancyUpdateRule::KL_DIVERGENCE:
      return "kl_divergence";
    case OccupancyUpdateRule::LOG_ODDS:
      return "log_odds";
  }
  return "unknown";
}

RangeErrorModel
rangeErrorModelFromString(const std::string& name)
{
  if (name == "stereo")
    return RangeErrorModel::STEREO;
  if (name == "depth_quadratic")
    return RangeErrorModel::DEPTH_QUADRATIC;
  if (name == "range")
    return RangeErrorModel::RANGE;
  throw Exception("Unknown range error model '" + name
                  + "' (known: stereo, depth_quadratic, range)");
}

std::string
toString(RangeErrorModel model)
{
  switch (model) {
    case RangeErrorModel::STEREO:
      return "stereo";
    case RangeErrorModel::DEPTH_QUADRATIC:
      return "depth_quadratic";
    case RangeErrorModel::RANGE:
      return "range";
  }
  return "unknown";
}

double
sampledGaussianOccupancy(double range_m, double mean_range_m, double range_error_m)
{
  if (!(std::isfinite(range_m) && std::isfinite(mean_range_m)
        && std::isfinite(range_error_m) && range_error_m > 0.0))
    return 0.0;
  if (range_m == mean_range_m)
    return 1.0;
  const double t = (range_m - mean_range_m) / range_error_m;
  return std::exp(-0.5 * t * t);
}

double
rangeOccupancyProbability(double range_m,
                          double mean_range_m,
                          double depth_m,
                          double focal_length_px,
                          double baseline_m,
                          double disparity_error_px)
{
  if (!(std::isfinite(range_m) && std::isfinite(mean_range_m) && std::isfinite(depth_m)
        && std::isfinite(focal_length_px) && std::isfinite(baseline_m)
        && std::isfinite(disparity_error_px)))
    return 0.0;
  if (!(depth_m > 0.0 && focal_length_px > 0.0 && baseline_m > 0.0
        && disparity_error_px > 0.0))
    return 0.0;
  if (range_m == mean_range_m)
    return 1.0;
  // dz = z^2 / (B f) dd; dr = (r_bar / z) dz (eq. 4).
  const double depth_error_m =
    depth_m * depth_m / (baseline_m * focal_length_px) * disparity_error_px;
  return sampledGaussianOccupancy(range_m, mean_range_m,
                                  mean_range_m / depth_m * depth_error_m);
}

double
bernoulliKLDivergence(double p, double q)
{
  if (std::isnan(p) || std::isnan(q))
    return std::numeric_limits<double>::quiet_NaN();
  p = std::min(std::max(p, 0.0), 1.0);
  q = std::min(std::max(q, KL_PROBABILITY_EPS), 1.0 - KL_PROBABILITY_EPS);
  // 0 ln 0 = 0: a term with a zero weight vanishes.
  const double occupied = p > 0.0 ? p * std::log(p / q) : 0.0;
  const double free = p < 1.0 ? (1.0 - p) * std::log((1.0 - p) / (1.0 - q)) : 0.0;
  return occupied + free;
}

double
klDivergenceUpdate(double p, double q, double offset_nats)
{
  double energy = std::abs(bernoulliKLDivergence(p, q));
  if (p <= 0.5 && q <= 0.5)
    energy += offset_nats;
  return std::exp(-energy);
}

const ParamDeclarations<KLDivergenceOccupancyFilterParams>&
klDivergenceOccupancyFilterParamDeclarations()
{
  using P = KLDivergenceOccupancyFilterParams;
  namespace ranges = kl_divergence_occupancy_filter_ranges;
  const auto update_rule_name = [](OccupancyUpdateRule rule) {
    return toString(rule);
  };
  static const ParamDeclarations<P> table = {
    declareChoice<P>(
      "update_rule", [](auto& p) -> auto& { return p.update_rule; },
      {"kl_divergence", "log_odds"}, update_rule_name, occupancyUpdateRuleFromString,
      "Update of a re-observed feature: eqs. 5-10 or OctoMap's log-odds."),
    declareReal<P>(
      "disparity_error_px", [](auto& p) -> auto& { return p.disparity_error_px; },
      ranges::DISPARITY_ERROR, "px", "dd of eq. 4 (stereo)."),
    declareReal<P>(
      "depth_error_coefficient_per_m",
      [](auto& p) -> auto& { return p.depth_error_coefficient_per_m; },
      ranges::DEPTH_ERROR_COEFFICIENT, "1/m",
      "k of dz = k z^2 (depth_quadratic); the default is 4 cm at 5 m, the Kinect's "
      "(Khoshelham and Elberink 2012)."),
    declareReal<P>(
      "range_error_m", [](auto& p) -> auto& { return p.range_error_m; },
      ranges::RANGE_ERROR, "m",
      "dr of eq. 4 (range): the sensor's range standard deviation."),
    declareReal<P>(
      "association_radius_m", [](auto& p) -> auto& { return p.association_radius_m; },
      ranges::ASSOCIATION_RADIUS, "m",
      "Features without descriptors: a feature continues the nearest track within "
      "this distance in the world."),
    declareReal<P>(
      "neighbourhood_size_m", [](auto& p) -> auto& { return p.neighbourhood_size_m; },
      ranges::NEIGHBOURHOOD_SIZE, "m", "Cell over which r_bar of eq. 4 is averaged."),
    declareReal<P>(
      "clamping_thres_min", [](auto& p) -> auto& { return p.clamping_thres_min; },
      ranges::CLAMPING_THRES_MIN, "probability", "Lower clamp of the probability."),
    declareReal<P>(
      "clamping_thres_max", [](auto& p) -> auto& { return p.clamping_thres_max; },
      ranges::CLAMPING_THRES_MAX, "probability", "Upper clamp of the probability."),
    declareReal<P>(
      "occupancy_thres", [](auto& p) -> auto& { return p.occupancy_thres; },
      ranges::OCCUPANCY_THRES, "probability",
      "A feature is occupied when its probability reaches it."),
    declareReal<P>(
      "kl_offset_nats", [](auto& p) -> auto& { return p.kl_offset_nats; },
      ranges::KL_OFFSET, "nats", "A of eq. 10."),
    declareReal<P>(
      "prob_hit", [](auto& p) -> auto& { return p.prob_hit; }, ranges::PROB_HIT,
      "probability", "Log-odds rule: a hit (q >= 0.5)."),
    declareReal<P>(
      "prob_miss", [](auto& p) -> auto& { return p.prob_miss; }, ranges::PROB_MISS,
      "probability", "Log-odds rule: a miss (q < 0.5)."),
  };
  return table;
}

} // namespace planar_grid

#ifndef PCL_NO_PRECOMPILE
#include <planar_grid/filters/impl/kl_divergence_occupancy_filter.hpp>
#include <planar_grid/point_types.h>

#include <pcl/point_types.h>

// One explicit instantiation per point type of the CMake list PLANAR_GRID_POINT_TYPES.
PLANAR_GRID_INSTANTIATE(KLDivergenceOccupancyFilter, PLANAR_GRID_POINT_TYPES)
#endif // PCL_NO_PRECOMPILE
