// SPDX-License-Identifier: BSD-3-Clause
#pragma once

#include <planar_grid/core/byte_io.h>
#include <planar_grid/core/log_odds.h>
#include <planar_grid/filters/kl_divergence_occupancy_filter.h>

#include <pcl/common/point_tests.h>
#include <pcl/console/print.h>

#include <Eigen/Geometry>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <limits>
#include <string>

namespace planar_grid {

namespace detail {

/** \brief Integer cell coordinate of \a value for cells of edge 1 / inv_size, clamped
 * to the 21 bits a packed key holds (+-2^20 cells). */
inline std::int64_t
cellCoordinate(double value, double inv_size)
{
  constexpr double LIMIT = 1048575.0; // 2^20 - 1
  const double c = std::floor(value * inv_size);
  return static_cast<std::int64_t>(std::min(std::max(c, -LIMIT), LIMIT));
}

/** \brief Packs three cell coordinates of cellCoordinate() into one 63-bit key. */
inline std::uint64_t
packCell(std::int64_t ix, std::int64_t iy, std::int64_t iz)
{
  constexpr std::int64_t OFFSET = 1048576; // 2^20
  constexpr std::uint64_t MASK = 0x1FFFFF;
  return (static_cast<std::uint64_t>(ix + OFFSET) & MASK)
         | ((static_cast<std::uint64_t>(iy + OFFSET) & MASK) << 21)
         | ((static_cast<std::uint64_t>(iz + OFFSET) & MASK) << 42);
}

/** \brief splitmix64's finaliser: a well-mixed hash of a packed cell key. */
inline std::uint64_t
mixKey(std::uint64_t key)
{
  key ^= key >> 30;
  key *= 0xbf58476d1ce4e5b9ULL;
  key ^= key >> 27;
  key *= 0x94d049bb133111ebULL;
  key ^= key >> 31;
  return key;
}

/** \brief Magic ("PGKT") and version of the track section. */
constexpr std::uint32_t TRACKS_MAGIC = 0x544B4750u;
constexpr std::uint32_t TRACKS_VERSION = 1;

} // namespace detail

template <typename PointT>
KLDivergenceOccupancyFilter<PointT>::KLDivergenceOccupancyFilter(
  bool extract_removed_indices) :
    pcl::FilterIndices<PointT>(extract_removed_indices)
{
  filter_name_ = "KLDivergenceOccupancyFilter";
}

template <typename PointT>
void
KLDivergenceOccupancyFilter<PointT>::setStereoParameters(double focal_length_px,
                                                         double baseline_m)
{
  focal_length_px_ = focal_length_px;
  baseline_m_ = baseline_m;
}

template <typename PointT>
double
KLDivergenceOccupancyFilter<PointT>::getClampingThresMinLogOdds() const
{
  return toLogOdds(params_.clamping_thres_min);
}

template <typename PointT>
double
KLDivergenceOccupancyFilter<PointT>::getClampingThresMaxLogOdds() const
{
  return toLogOdds(params_.clamping_thres_max);
}

template <typename PointT>
double
KLDivergenceOccupancyFilter<PointT>::getOccupancyThresLogOdds() const
{
  return toLogOdds(params_.occupancy_thres);
}

template <typename PointT>
double
KLDivergenceOccupancyFilter<PointT>::getProbHitLogOdds() const
{
  return toLogOdds(params_.prob_hit);
}

template <typename PointT>
double
KLDivergenceOccupancyFilter<PointT>::getProbMissLogOdds() const
{
  return toLogOdds(params_.prob_miss);
}

template <typename PointT>
void
KLDivergenceOccupancyFilter<PointT>::setInputCloud(const PointCloudConstPtr& cloud)
{
  pcl::FilterIndices<PointT>::setInputCloud(cloud);
  markInputChanged();
}

template <typename PointT>
void
KLDivergenceOccupancyFilter<PointT>::setTrackIds(
  const std::vector<std::int64_t>& track_ids)
{
  track_ids_ = track_ids;
  markInputChanged();
}

template <typename PointT>
void
KLDivergenceOccupancyFilter<PointT>::setMotionLikelihood(double motion_likelihood)
{
  motion_likelihood_ = motion_likelihood;
  markInputChanged();
}

template <typename PointT>
void
KLDivergenceOccupancyFilter<PointT>::reset()
{
  tracks_.clear();
  association_cells_.clear();
  association_cells_valid_ = false;
  next_track_id_ = 0;
  frame_count_ = 0;
  markInputChanged();
  integrated_input_.reset();
  integrated_indices_.reset();
  probabilities_.clear();
  assigned_track_ids_.clear();
}

template <typename PointT>
std::size_t
KLDivergenceOccupancyFilter<PointT>::retainTracks(
  const std::vector<std::int64_t>& track_ids)
{
  const std::size_t before = tracks_.size();
  std::unordered_map<std::int64_t, Track> kept;
  kept.reserve(track_ids.size());
  for (const std::int64_t id : track_ids) {
    const auto found = tracks_.find(id);
    if (found != tracks_.end())
      kept.emplace(id, found->second);
  }
  tracks_.swap(kept);
  const std::size_t removed = before - tracks_.size();
  if (removed > 0) {
    // The position index is rebuilt from the tracks left at the next association.
    association_cells_.clear();
    association_cells_valid_ = false;
  }
  return removed;
}

template <typename PointT>
void
KLDivergenceOccupancyFilter<PointT>::serializeTracks(
  std::vector<std::uint8_t>& bytes) const
{
  ByteWriter w(bytes);
  w.put(detail::TRACKS_MAGIC);
  w.put(detail::TRACKS_VERSION);
  w.put(frame_count_);
  w.put(next_track_id_);
  w.put(static_cast<std::uint64_t>(tracks_.size()));
  std::vector<std::int64_t> ids;
  ids.reserve(tracks_.size());
  for (const auto& kv : tracks_)
    ids.push_back(kv.first);
  std::sort(ids.begin(), ids.end());
  for (const auto id : ids) {
    const Track& t = tracks_.find(id)->second;
    w.put(id);
    w.put(t.log_odds);
    for (int k = 0; k < 3; ++k)
      w.put(t.position[k]);
    w.put(t.observations);
    w.put(t.last_frame);
  }
}

template <typename PointT>
void
KLDivergenceOccupancyFilter<PointT>::deserializeTracks(const std::uint8_t* data,
                                                       std::size_t size)
{
  ByteReader r(data, size, "KL filter tracks");
  if (r.get<std::uint32_t>() != detail::TRACKS_MAGIC)
    r.fail("not a track section (magic)");
  if (r.get<std::uint32_t>() != detail::TRACKS_VERSION)
    r.fail("unsupported version");
  const auto frame_count = r.get<std::uint32_t>();
  const auto next_id = r.get<std::int64_t>();
  constexpr std::size_t TRACK_BYTES = 8 + 4 * 4 + 4 + 4;
  const std::size_t n = r.getCount(TRACK_BYTES, "track");
  std::unordered_map<std::int64_t, Track> tracks;
  tracks.reserve(n);
  for (std::size_t k = 0; k < n; ++k) {
    const auto id = r.get<std::int64_t>();
    Track t;
    t.log_odds = r.get<float>();
    for (int c = 0; c < 3; ++c)
      t.position[c] = r.get<float>();
    t.observations = r.get<std::uint32_t>();
    t.last_frame = r.get<std::uint32_t>();
    if (id < 0 || !std::isfinite(t.log_odds) || !t.position.allFinite())
      r.fail("invalid track " + std::to_string(id));
    if (!tracks.emplace(id, t).second)
      r.fail("track id " + std::to_string(id) + " given twice");
  }
  if (r.remaining() != 0)
    r.fail(std::to_string(r.remaining()) + " bytes of trailing data");
  reset();
  tracks_ = std::move(tracks);
  frame_count_ = frame_count;
  next_track_id_ = next_id;
}

template <typename PointT>
bool
KLDivergenceOccupancyFilter<PointT>::getTrackProbability(std::int64_t track_id,
                                                         float& probability) const
{
  const auto it = tracks_.find(track_id);
  if (it == tracks_.end())
    return false;
  probability = static_cast<float>(toProbability(it->second.log_odds));
  return true;
}

template <typename PointT>
std::size_t
KLDivergenceOccupancyFilter<PointT>::getMemoryBytes() const
{
  // A node of an unordered_map holds the value and a next pointer (libstdc++ also
  // caches no hash for integer keys); each bucket is one pointer.
  std::size_t bytes =
    tracks_.size() * (sizeof(std::pair<const std::int64_t, Track>) + sizeof(void*))
    + tracks_.bucket_count() * sizeof(void*);
  for (const auto& cell : association_cells_)
    bytes +=
      sizeof(cell) + sizeof(void*) + cell.second.capacity() * sizeof(std::int64_t);
  bytes += association_cells_.bucket_count() * sizeof(void*);
  bytes += cells_.capacity() * sizeof(CellSum) + ranges_m_.capacity() * sizeof(double)
           + depths_m_.capacity() * sizeof(double)
           + cell_slots_.capacity() * sizeof(std::uint32_t)
           + probabilities_.capacity() * sizeof(float)
           + assigned_track_ids_.capacity() * sizeof(std::int64_t)
           + track_ids_.capacity() * sizeof(std::int64_t);
  return bytes;
}

template <typename PointT>
const char*
KLDivergenceOccupancyFilter<PointT>::checkParameters() const
{
  const Params& p = params_;
  if (p.range_error_model != RangeErrorModel::STEREO
      && p.range_error_model != RangeErrorModel::DEPTH_QUADRATIC
      && p.range_error_model != RangeErrorModel::RANGE)
    return "range_error_model must be STEREO, DEPTH_QUADRATIC or RANGE";
  if (p.range_error_model == RangeErrorModel::STEREO
      && !(std::isfinite(focal_length_px_) && focal_length_px_ > 0.0
           && std::isfinite(baseline_m_) && baseline_m_ > 0.0))
    return "stereo parameters not set (setStereoParameters(f > 0 px, B > 0 m))";
  if (p.update_rule != OccupancyUpdateRule::KL_DIVERGENCE
      && p.update_rule != OccupancyUpdateRule::LOG_ODDS)
    return "update_rule must be KL_DIVERGENCE or LOG_ODDS";
  namespace ranges = kl_divergence_occupancy_filter_ranges;
  // One message per range, written from the range once (static: the returned pointer
  // stays valid).
  static const std::array<std::string, 12> messages{
    paramRangeMessage("depth_error_coefficient_per_m", ranges::DEPTH_ERROR_COEFFICIENT,
                      "1/m"),
    paramRangeMessage("range_error_m", ranges::RANGE_ERROR, "m"),
    paramRangeMessage("disparity_error_px", ranges::DISPARITY_ERROR, "px"),
    paramRangeMessage("neighbourhood_size_m", ranges::NEIGHBOURHOOD_SIZE, "m"),
    paramRangeMessage("clamping_thres_min", ranges::CLAMPING_THRES_MIN),
    paramRangeMessage("clamping_thres_max", ranges::CLAMPING_THRES_MAX),
    paramRangeMessage("occupancy_thres", ranges::OCCUPANCY_THRES),
    paramRangeMessage("kl_offset_nats", ranges::KL_OFFSET, "nats"),
    paramRangeMessage("prob_hit", ranges::PROB_HIT),
    paramRangeMessage("prob_miss", ranges::PROB_MISS),
    paramRangeMessage("association_radius_m", ranges::ASSOCIATION_RADIUS, "m"),
    paramRangeMessage("the motion likelihood", ranges::MOTION_LIKELIHOOD)};
  const std::array<bool, 12> valid{
    ranges::DEPTH_ERROR_COEFFICIENT.contains(p.depth_error_coefficient_per_m),
    ranges::RANGE_ERROR.contains(p.range_error_m),
    ranges::DISPARITY_ERROR.contains(p.disparity_error_px),
    ranges::NEIGHBOURHOOD_SIZE.contains(p.neighbourhood_size_m),
    ranges::CLAMPING_THRES_MIN.contains(p.clamping_thres_min),
    ranges::CLAMPING_THRES_MAX.contains(p.clamping_thres_max),
    ranges::OCCUPANCY_THRES.contains(p.occupancy_thres),
    ranges::KL_OFFSET.contains(p.kl_offset_nats),
    ranges::PROB_HIT.contains(p.prob_hit),
    ranges::PROB_MISS.contains(p.prob_miss),
    ranges::ASSOCIATION_RADIUS.contains(p.association_radius_m),
    ranges::MOTION_LIKELIHOOD.contains(motion_likelihood_)};
  for (std::size_t i = 0; i < valid.size(); ++i)
    if (!valid[i])
      return messages[i].c_str();
  if (!track_ids_.empty() && track_ids_.size() != input_->size())
    return "the track ids must be one per input point";
  return nullptr;
}

template <typename PointT>
void
KLDivergenceOccupancyFilter<PointT>::resetOutputs()
{
  const std::size_t n = input_ ? input_->size() : 0;
  probabilities_.assign(n, 0.0f);
  assigned_track_ids_.assign(n, -1);
}

template <typename PointT>
std::uint64_t
KLDivergenceOccupancyFilter<PointT>::associationKey(
  const Eigen::Vector3f& position) const
{
  const double inv = 1.0 / association_cell_size_m_;
  return detail::packCell(detail::cellCoordinate(position.x(), inv),
                          detail::cellCoordinate(position.y(), inv),
                          detail::cellCoordinate(position.z(), inv));
}

template <typename PointT>
void
KLDivergenceOccupancyFilter<PointT>::rebuildAssociationCells()
{
  association_cells_.clear();
  association_cell_size_m_ = params_.association_radius_m;
  for (const auto& track : tracks_)
    association_cells_[associationKey(track.second.position)].push_back(track.first);
  association_cells_valid_ = true;
}

template <typename PointT>
void
KLDivergenceOccupancyFilter<PointT>::moveAssociation(std::int64_t id,
                                                     std::uint64_t old_key,
                                                     std::uint64_t new_key)
{
  if (old_key == new_key)
    return;
  const auto it = association_cells_.find(old_key);
  if (it != association_cells_.end()) {
    std::vector<std::int64_t>& ids = it->second;
    const auto pos = std::find(ids.begin(), ids.end(), id);
    if (pos != ids.end()) {
      *pos = ids.back();
      ids.pop_back();
    }
    if (ids.empty())
      association_cells_.erase(it);
  }
  association_cells_[new_key].push_back(id);
}

template <typename PointT>
std::int64_t
KLDivergenceOccupancyFilter<PointT>::associate(const Eigen::Vector3f& position) const
{
  const double inv = 1.0 / association_cell_size_m_;
  const std::int64_t cx = detail::cellCoordinate(position.x(), inv);
  const std::int64_t cy = detail::cellCoordinate(position.y(), inv);
  const std::int64_t cz = detail::cellCoordinate(position.z(), inv);
  const double radius = params_.association_radius_m;
  double best_sq = radius * radius;
  std::int64_t best = -1;
  // The cubes have edge = radius, so every track within the radius is in one of the
  // 27 cubes around the feature's.
  for (std::int64_t dz = -1; dz <= 1; ++dz)
    for (std::int64_t dy = -1; dy <= 1; ++dy)
      for (std::int64_t dx = -1; dx <= 1; ++dx) {
        const auto it =
          association_cells_.find(detail::packCell(cx + dx, cy + dy, cz + dz));
        if (it == association_cells_.end())
          continue;
        for (const std::int64_t id : it->second) {
          const Track& track = tracks_.at(id);
          if (track.last_frame == frame_count_)
            continue; // taken by an earlier feature of this frame
          const Eigen::Vector3f offset = track.position - position;
          const double d_sq = static_cast<double>(offset.squaredNorm());
          if (d_sq <= best_sq && (best < 0 || d_sq < best_sq || id < best)) {
            best_sq = d_sq;
            best = id;
          }
        }
      }
  return best;
}

template <typename PointT>
std::size_t
KLDivergenceOccupancyFilter<PointT>::sumNeighbourhoodRanges()
{
  const PointCloud& cloud = *input_;
  const pcl::Indices& indices = *indices_;
  const std::size_t n = indices.size();
  ranges_m_.resize(n);
  depths_m_.resize(n);
  cell_slots_.resize(n);

  // Sensor pose of the input: p_sensor = R^T (p - origin).
  const Eigen::Vector3d origin =
    input_->sensor_origin_.template head<3>().template cast<double>();
  const Eigen::Matrix3d rotation_t = input_->sensor_orientation_.template cast<double>()
                                       .normalized()
                                       .toRotationMatrix()
                                       .transpose();

  // Open-addressing table of the neighbourhood cells, >= 2n slots (power of two).
  std::size_t capacity = 16;
  while (capacity < 2 * n)
    capacity *= 2;
  if (cells_.size() < capacity)
    cells_.resize(capacity);
  std::fill(cells_.begin(), cells_.begin() + static_cast<std::ptrdiff_t>(capacity),
            CellSum{});
  const std::size_t mask = capacity - 1;
  const double inv_size = 1.0 / params_.neighbourhood_size_m;

  const bool range_model = params_.range_error_model == RangeErrorModel::RANGE;
  std::size_t valid = 0;
  for (std::size_t k = 0; k < n; ++k) {
    depths_m_[k] = 0.0;
    const pcl::index_t index = indices[k];
    if (index < 0 || static_cast<std::size_t>(index) >= cloud.size())
      continue;
    const PointT& point = cloud[index];
    if (!pcl::isXYZFinite(point))
      continue;
    const Eigen::Vector3d sensor =
      rotation_t * (point.getVector3fMap().template cast<double>() - origin);
    // A camera sees only what is in front of it; a range sensor measures in every
    // direction, so there only the range must be positive.
    const double depth_m = range_model ? sensor.norm() : sensor.z();
    if (!(depth_m > 0.0))
      continue;
    ranges_m_[k] = sensor.norm();
    depths_m_[k] = depth_m;
    const std::uint64_t key =
      detail::packCell(detail::cellCoordinate(sensor.x(), inv_size),
                       detail::cellCoordinate(sensor.y(), inv_size),
                       detail::cellCoordinate(sensor.z(), inv_size));
    std::size_t slot = detail::mixKey(key) & mask;
    while (cells_[slot].count != 0 && cells_[slot].key != key)
      slot = (slot + 1) & mask;
    cells_[slot].key = key;
    cells_[slot].range_sum_m += ranges_m_[k];
    ++cells_[slot].count;
    cell_slots_[k] = static_cast<std::uint32_t>(slot);
    ++valid;
  }
  return valid;
}

template <typename PointT>
double
KLDivergenceOccupancyFilter<PointT>::featureProbability(std::size_t k) const
{
  const CellSum& cell = cells_[cell_slots_[k]];
  const double mean_range_m = cell.range_sum_m / cell.count;
  double p_eq4 = 0.0;
  switch (params_.range_error_model) {
    case RangeErrorModel::STEREO:
      p_eq4 = rangeOccupancyProbability(ranges_m_[k], mean_range_m, depths_m_[k],
                                        focal_length_px_, baseline_m_,
                                        params_.disparity_error_px);
      break;
    case RangeErrorModel::DEPTH_QUADRATIC:
      // dz = k z^2, dr = (r_bar / z) dz = r_bar k z.
      p_eq4 = sampledGaussianOccupancy(
        ranges_m_[k], mean_range_m,
        mean_range_m * params_.depth_error_coefficient_per_m * depths_m_[k]);
      break;
    case RangeErrorModel::RANGE:
      p_eq4 =
        sampledGaussianOccupancy(ranges_m_[k], mean_range_m, params_.range_error_m);
      break;
  }
  return std::min(std::max(p_eq4, params_.clamping_thres_min),
                  params_.clamping_thres_max);
}

template <typename PointT>
void
KLDivergenceOccupancyFilter<PointT>::updateTrack(std::size_t index,
                                                 double p_new,
                                                 const Eigen::Vector3f& position,
                                                 bool by_position,
                                                 const TrackUpdate& update)
{
  std::int64_t id = -1;
  if (by_position)
    id = associate(position);
  else
    id = track_ids_[index];
  if (by_position && id < 0)
    id = next_track_id_; // a new track
  if (id < 0) {
    probabilities_[index] = static_cast<float>(p_new);
    return;
  }
  next_track_id_ = std::max(next_track_id_, id + 1);
  assigned_track_ids_[index] = id;

  const auto found = tracks_.find(id);
  if (found == tracks_.end()) {
    Track& track = tracks_[id];
    track.log_odds = static_cast<float>(toLogOdds(p_new));
    track.position = position;
    track.observations = 1;
    track.last_frame = frame_count_;
    if (by_position)
      association_cells_[associationKey(position)].push_back(id);
    probabilities_[index] = static_cast<float>(p_new);
    return;
  }
  Track& track = found->second;
  if (track.last_frame != frame_count_) {
    const double q = p_new * motion_likelihood_; // eq. 7
    double log_odds = track.log_odds;
    if (params_.update_rule == OccupancyUpdateRule::KL_DIVERGENCE) {
      const double p = toProbability(log_odds);
      const double updated = klDivergenceUpdate(p, q, params_.kl_offset_nats);
      log_odds = toLogOdds(std::min(std::max(updated, update.p_min), update.p_max));
    } else {
      log_odds += q >= 0.5 ? update.log_odds_hit : update.log_odds_miss;
      log_odds = std::min(std::max(log_odds, update.log_odds_min), update.log_odds_max);
    }
    track.log_odds = static_cast<float>(log_odds);
    if (by_position)
      moveAssociation(id, associationKey(track.position), associationKey(position));
    track.position = position;
    ++track.observations;
    track.last_frame = frame_count_;
  }
  probabilities_[index] = static_cast<float>(toProbability(track.log_odds));
}

template <typename PointT>
std::size_t
KLDivergenceOccupancyFilter<PointT>::integrate()
{
  // Pass 1: range, depth and cell of every valid point; the cells' range sums.
  const std::size_t valid = sumNeighbourhoodRanges();
  if (valid == 0)
    return 0;

  ++frame_count_;
  const bool by_position = track_ids_.empty();
  if (by_position) {
    if (!association_cells_valid_
        || association_cell_size_m_ != params_.association_radius_m)
      rebuildAssociationCells();
  } else {
    association_cells_valid_ = false; // positions change without the hash
  }

  // Pass 2: eq. 4, then the track's first value or its update (eqs. 5-10).
  const TrackUpdate update{params_.clamping_thres_min,
                           params_.clamping_thres_max,
                           toLogOdds(params_.clamping_thres_min),
                           toLogOdds(params_.clamping_thres_max),
                           toLogOdds(params_.prob_hit),
                           toLogOdds(params_.prob_miss)};
  const pcl::Indices& indices = *indices_;
  for (std::size_t k = 0; k < indices.size(); ++k) {
    if (!(depths_m_[k] > 0.0))
      continue;
    const auto index = static_cast<std::size_t>(indices[k]);
    updateTrack(index, featureProbability(k), (*input_)[index].getVector3fMap(),
                by_position, update);
  }
  return valid;
}

template <typename PointT>
void
KLDivergenceOccupancyFilter<PointT>::applyFilter(pcl::Indices& indices)
{
  indices.clear();
  removed_indices_->clear();

  const char* bad = checkParameters();
  if (bad != nullptr) {
    PCL_ERROR("[planar_grid::%s::filter] Invalid parameter: %s.\n",
              this->getClassName().c_str(), bad);
    resetOutputs();
    markInputChanged();
    return;
  }
  if (input_->empty() || indices_->empty()) {
    PCL_WARN("[planar_grid::%s::filter] Empty input.\n", this->getClassName().c_str());
    resetOutputs();
    markInputChanged();
    return;
  }

  if (!input_integrated_ || input_ != integrated_input_
      || indices_ != integrated_indices_) {
    resetOutputs();
    const std::size_t valid = integrate();
    input_integrated_ = true;
    integrated_input_ = input_;
    integrated_indices_ = indices_;
    motion_likelihood_ = 1.0; // m applies to one update only
    if (valid == 0) {
      PCL_WARN("[planar_grid::%s::filter] No finite point in front of the sensor.\n",
               this->getClassName().c_str());
      return;
    }
  }

  // Selection. A valid point's probability is >= clamping_thres_min > 0, so 0 marks an
  // invalid one; invalid points are never kept, in either mode.
  indices.reserve(indices_->size());
  for (const pcl::index_t index : *indices_) {
    const bool in_range =
      index >= 0 && static_cast<std::size_t>(index) < input_->size();
    const float probability = in_range ? probabilities_[index] : 0.0f;
    bool keep = false;
    if (probability > 0.0f) {
      keep = static_cast<double>(probability) >= params_.occupancy_thres;
      if (negative_)
        keep = !keep;
    }
    if (keep)
      indices.push_back(index);
    else if (extract_removed_indices_)
      removed_indices_->push_back(index);
  }
}

} // namespace planar_grid

#define PLANAR_GRID_INSTANTIATE_KLDivergenceOccupancyFilter(T) \
  template class planar_grid::KLDivergenceOccupancyFilter<T>;
