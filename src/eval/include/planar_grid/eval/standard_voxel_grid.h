// SPDX-License-Identifier: BSD-3-Clause
#pragma once

#include <pcl/point_cloud.h>
#include <pcl/point_types.h>

#include <Eigen/Core>

#include <cstddef>
#include <cstdint>
#include <memory>
#include <unordered_map>
#include <vector>

namespace planar_grid {

/** \brief Integer voxel index of a point p: floor(p / resolution_m) per axis, computed
 * as floor(p (1 / resolution_m)) like OctoMap's coordToKey (the two differ only within
 * rounding of a cell border). \ingroup eval */
using VoxelIndex = Eigen::Vector3i;

/** \brief SG, the standard occupancy voxel grid of the comparison in Sec. IV-B of
 * the paper ("Efficient Planar Surface-Based 3D Mapping Method for Mobile Robots Using
 * Stereo Vision") (Figs. 12-14): one log-odds value per observed cubic voxel of edge
 * resolution_m, in a hash map keyed by the packed index (3 x 21 bits, z in the high
 * bits).
 *
 * The sensor model and update are OctoMap's (Hornung et al. 2013, liboctomap 1.9
 * OccupancyOcTreeBase): probabilities at the boundary, log-odds inside; an observed
 * voxel starts at log-odds 0, each update adds logit(prob_hit) or logit(prob_miss)
 * and clamps to [logit(clamping_thres_min), logit(clamping_thres_max)]. A scan is
 * inserted like octomap::OcTree::insertPointCloud(scan, sensor_origin, max_range,
 * lazy_eval = false, discretize = false):
 * - each ray from sensor_origin to an end point is traced with the 3D-DDA of
 *   Amanatides & Woo (the same arithmetic as OcTreeBaseImpl::computeRayKeys, floats
 *   where OctoMap has floats, doubles where it has doubles); the voxels before the end
 *   point's voxel are free, the end point's voxel is occupied;
 * - per scan each voxel is updated at most once (a flat open-addressing hash set
 *   collects the scan's voxels), and a voxel holding an end point is updated as
 *   occupied even when another ray passes through it (occupied wins);
 * - an end point farther than max_range_m from sensor_origin (max_range_m > 0) clears
 *   free space along its ray up to max_range_m and marks nothing;
 * - non-finite points are skipped; a point, or ray, whose voxel lies outside the
 *   index range [-(2^20 - 1), 2^20 - 1] per axis is skipped like OctoMap's
 *   coordToKeyChecked() failures (end point in range: still marked occupied).
 *
 * With the same parameters the voxels and log-odds equal those of an OcTree fed the
 * same scans (the tests check this exactly, voxel by voxel).
 *
 * An empty cloud changes nothing. Voxel occupancy (isOccupied(), getOccupiedCount())
 * is log_odds >= logit(occupancy_thres), the test of OctoMap's isNodeOccupied().
 * \ingroup eval */
class StandardVoxelGrid {
public:
  using Ptr = std::shared_ptr<StandardVoxelGrid>;
  using ConstPtr = std::shared_ptr<const StandardVoxelGrid>;
  using PointCloud = pcl::PointCloud<pcl::PointXYZ>;
  using PointCloudPtr = PointCloud::Ptr;
  using PointCloudConstPtr = PointCloud::ConstPtr;

  /** \brief Parameters with OctoMap's defaults and the valid ranges (the constructor
   * throws outside them). Each probability's log-odds form is given by the matching
   * get...LogOdds() getter. */
  struct Params {
    /** Voxel edge, meters; in (0, 100]. */
    double resolution_m{0.1};
    /** Longest ray integrated, meters; <= 0: unlimited. */
    double max_range_m{-1.0};
    /** Probability of an occupied end point, in (0.5, 1); log-odds 0.8473. */
    float prob_hit{0.7f};
    /** Probability of a traversed voxel, in (0, 0.5); log-odds -0.4055. */
    float prob_miss{0.4f};
    /** Lower clamping bound, probability in (0, 0.5]; log-odds -1.9990. */
    float clamping_thres_min{0.1192f};
    /** Upper clamping bound, probability in [0.5, 1); log-odds 3.5112. */
    float clamping_thres_max{0.971f};
    /** Occupancy threshold, probability in (0, 1), inside [clamping_thres_min,
     * clamping_thres_max]; log-odds 0. */
    float occupancy_thres{0.5f};
  };

  /** \brief One observed voxel. */
  struct Voxel {
    /** \brief Its index. */
    VoxelIndex index;
    /** \brief Its log-odds. */
    float log_odds;
  };

  /** \brief Largest |index| per axis (2^20 - 1): 104.8 km at 0.1 m. */
  static constexpr int MAX_INDEX = (1 << 20) - 1;

  /** \brief An empty grid.
   * \param[in] params the parameters
   * \throws planar_grid::Exception when a parameter is outside its range */
  explicit StandardVoxelGrid(const Params& params);
  StandardVoxelGrid(const StandardVoxelGrid&) = delete;
  StandardVoxelGrid& operator=(const StandardVoxelGrid&) = delete;
  StandardVoxelGrid(StandardVoxelGrid&&) noexcept = default;
  StandardVoxelGrid& operator=(StandardVoxelGrid&&) noexcept = default;
  ~StandardVoxelGrid() = default;

  /** \brief The parameters. */
  const Params& getParams() const { return params_; }
  /** \brief logit(prob_hit), the update of an occupied voxel (log-odds). */
  [[nodiscard]] float getProbHitLogOdds() const { return prob_hit_log_odds_; }
  /** \brief logit(prob_miss), the update of a free voxel (log-odds). */
  [[nodiscard]] float getProbMissLogOdds() const { return prob_miss_log_odds_; }
  /** \brief logit(clamping_thres_min) (log-odds). */
  [[nodiscard]] float getClampingThresMinLogOdds() const { return clamping_min_; }
  /** \brief logit(clamping_thres_max) (log-odds). */
  [[nodiscard]] float getClampingThresMaxLogOdds() const { return clamping_max_; }
  /** \brief logit(occupancy_thres) (log-odds). */
  [[nodiscard]] float getOccupancyThresLogOdds() const { return occupancy_log_odds_; }

  /** \brief Integrates one scan (see the class description).
   * \param[in] cloud end points in the grid's frame, meters (non-finite ones skipped)
   * \param[in] sensor_origin start of every ray, meters (a non-finite or out-of-range
   * origin integrates the end points only, with a PCL_WARN) */
  void insertPointCloud(const pcl::PointCloud<pcl::PointXYZ>& cloud,
                        const Eigen::Vector3f& sensor_origin);

  /** \brief Index of the voxel containing \a point, meters (floor(p / resolution_m)
   * as described at VoxelIndex; no range check). */
  [[nodiscard]] VoxelIndex toIndex(const Eigen::Vector3f& point) const;
  /** \brief Centre of voxel \a index, meters ((index + 0.5) resolution_m). */
  [[nodiscard]] Eigen::Vector3f toCentre(const VoxelIndex& index) const;

  /** \brief Number of observed voxels. */
  [[nodiscard]] std::size_t getVoxelCount() const { return voxels_.size(); }
  /** \brief Number of occupied voxels (log-odds >= getOccupancyThresLogOdds()). */
  [[nodiscard]] std::size_t getOccupiedCount() const;
  /** \brief Number of observed voxels that are not occupied. */
  [[nodiscard]] std::size_t getFreeCount() const;
  /** \brief Whether voxel \a index is occupied; false when unobserved or out of
   * range. */
  [[nodiscard]] bool isOccupied(const VoxelIndex& index) const;
  /** \brief Log-odds of voxel \a index.
   * \param[in] index the voxel
   * \param[out] log_odds its log-odds (unchanged when unobserved)
   * \return false when the voxel is unobserved or out of range */
  bool getLogOdds(const VoxelIndex& index, float& log_odds) const;
  /** \brief Every observed voxel, sorted by (z, y, x) (deterministic).
   * \param[out] voxels the voxels (replaced) */
  void getVoxels(std::vector<Voxel>& voxels) const;
  /** \brief Centres of the occupied voxels, meters, sorted by (z, y, x); a 1 x N
   * unorganized cloud (replaced). */
  void getOccupiedCentres(pcl::PointCloud<pcl::PointXYZ>& centres) const;
  /** \brief Bytes held by the map, measured from the container as
   * surface_layer.cpp's hashMapBytes() measures PG's hash maps: bucket_count
   * pointers plus, per voxel, one node of (next pointer + key and log-odds + cached
   * hash) rounded up to 8 bytes. The per-scan scratch table of insertPointCloud()
   * (capacity kept between scans) is not part of the map and not counted, as
   * OctoMap's memoryUsage() leaves out its ray buffers. */
  [[nodiscard]] std::size_t getMemoryBytes() const;
  /** \brief Removes every voxel (and frees the scratch table). */
  void clear();

private:
  /** \brief Hash of a packed index (a 64-bit mix). */
  struct KeyHash {
    std::size_t operator()(std::uint64_t key) const noexcept
    {
      key ^= key >> 31;
      key *= 0x9E3779B97F4A7C15ULL;
      return static_cast<std::size_t>(key ^ (key >> 29));
    }
  };

  /** \brief The validated parameters. */
  Params params_;
  /** \brief 1 / resolution_m, as OctoMap's resolution_factor. */
  double inv_resolution_{10.0};
  /** \brief logit(prob_hit). */
  float prob_hit_log_odds_{0.0f};
  /** \brief logit(prob_miss). */
  float prob_miss_log_odds_{0.0f};
  /** \brief logit(clamping_thres_min). */
  float clamping_min_{0.0f};
  /** \brief logit(clamping_thres_max). */
  float clamping_max_{0.0f};
  /** \brief logit(occupancy_thres). */
  float occupancy_log_odds_{0.0f};
  /** \brief The observed voxels: packed index -> log-odds. */
  std::unordered_map<std::uint64_t, float, KeyHash> voxels_;
  /** \brief Per-scan scratch: open-addressing slots holding a packed index (0 =
   * empty) with bit 63 set for an end point (occupied). */
  std::vector<std::uint64_t> scratch_;
};

} // namespace planar_grid
