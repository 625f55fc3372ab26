// SPDX-License-Identifier: BSD-3-Clause
// Shared by the sources of the map comparison that run the methods: a lane (one cell
// size's PG pipeline and SG and OG maps), the REFERENCE truth's voxels, the ground
// truth (map_comparison_truth.cpp) and a lane's measurement against it
// (map_comparison_measure.cpp).
#pragma once

#include <planar_grid/eval/map_comparison.h>
#include <planar_grid/eval/mapping_error.h>
#include <planar_grid/eval/standard_voxel_grid.h>
#include <planar_grid/pipeline/pipeline_runner.h>

#include <pcl/point_cloud.h>
#include <pcl/point_types.h>

#include <octomap/octomap.h>

#include <chrono>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <limits>
#include <memory>
#include <string>
#include <unordered_map>
#include <utility>
#include <vector>

namespace planar_grid {
namespace detail {

inline double
msSince(std::chrono::steady_clock::time_point t)
{
  return std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t)
    .count();
}

/** The REFERENCE truth: voxels of all frames' points with the number of frames that
 * saw each; a point farther than max_range_m from its frame's camera is left out. */
class ReferenceVoxels {
public:
  ReferenceVoxels(double leaf_m, double max_range_m) :
      leaf_m_(leaf_m), max_range_sq_(max_range_m * max_range_m)
  {}

  /** \brief Adds one frame's \a points (world frame, m) seen from \a sensor_origin. */
  void addFrame(const pcl::PointCloud<pcl::PointXYZ>& points,
                const Eigen::Vector3f& sensor_origin)
  {
    ++frame_;
    for (const auto& p : points.points) {
      if (!(static_cast<double>((p.getVector3fMap() - sensor_origin).squaredNorm())
            <= max_range_sq_))
        continue;
      const auto key = keyOf(p.getVector3fMap());
      Voxel& v = voxels_[key];
      if (v.last_frame != frame_) {
        v.last_frame = frame_;
        ++v.views;
      }
      v.sum += p.getVector3fMap().cast<double>();
      ++v.points;
    }
  }

  /** The mean point of every voxel seen by at least \a min_views frames. */
  void getPoints(std::size_t min_views, pcl::PointCloud<pcl::PointXYZ>& out) const
  {
    out.clear();
    for (const auto& kv : voxels_)
      if (kv.second.views >= min_views) {
        const Eigen::Vector3d c = kv.second.sum / static_cast<double>(kv.second.points);
        out.push_back(pcl::PointXYZ(static_cast<float>(c.x()),
                                    static_cast<float>(c.y()),
                                    static_cast<float>(c.z())));
      }
  }

private:
  struct Voxel {
    Eigen::Vector3d sum{Eigen::Vector3d::Zero()};
    std::uint32_t points{0};
    std::uint32_t views{0};
    std::uint32_t last_frame{0};
  };

  std::uint64_t keyOf(const Eigen::Vector3f& p) const
  {
    std::uint64_t key = 0;
    for (int k = 0; k < 3; ++k) {
      const auto i = static_cast<std::int64_t>(std::floor(p[k] / leaf_m_)) + (1 << 20);
      key = (key << 21) | (static_cast<std::uint64_t>(i) & 0x1FFFFF);
    }
    return key;
  }

  double leaf_m_;
  double max_range_sq_;
  std::uint32_t frame_{0};
  std::unordered_map<std::uint64_t, Voxel> voxels_;
};

/** Milliseconds of each method's own work, to be reported per frame. */
struct MethodTimes {
  double sg{0.0}, og{0.0}, pg{0.0};
};

/** One cell size: PG's mapping stages (a pipeline fed the front end's frames), and
 * the SG and OG maps. */
struct Lane {
  double resolution_m{0.1};
  /** The mapping stages at this cell size; its state holds PG's map. */
  std::unique_ptr<PipelineRunner> pipeline;
  /** The stage types of \a pipeline, in order. */
  std::vector<std::string> types;
  std::unique_ptr<StandardVoxelGrid> sg;
  std::unique_ptr<octomap::OcTree> og;
  double pg_ms{0.0}, sg_ms{0.0}, og_ms{0.0};
  /** The current frame's times, and whether SG and OG have its cloud. */
  MethodTimes frame_ms;
  bool inserted{false};
  /** The truth voxelized at the lane's cell size (built when first measured). */
  std::unique_ptr<TruthVoxels> truth_voxels;
  /** Time spent on the completeness and planar share (and the truth voxels), ms. */
  double completeness_ms{0.0};
  /** Time spent on PG's plane precision, ms. */
  double plane_precision_ms{0.0};
  /** The views of the frames mapped so far already added to truth_voxels' range. */
  std::size_t views_added{0};
};

/** The frames mapped so far, for the mapped range, and its depth. */
struct MappedViews {
  double max_depth_m{std::numeric_limits<double>::infinity()};
  std::vector<RangeView, Eigen::aligned_allocator<RangeView>> views;
};

/** The view of \a frame for the mapped range (map_comparison_truth.cpp). */
RangeView rangeView(const Frame& frame);

/** The ground truth of \a ds (map_comparison_truth.cpp). */
std::unique_ptr<GroundTruthSurface> buildTruth(const DatasetConfig& ds,
                                               const Frame& first_frame,
                                               const ReferenceVoxels& reference,
                                               std::string& truth_kind);

/** SG, OG, RA and PG of \a lane as they stand, against \a truth
 * (map_comparison_measure.cpp). */
std::vector<ComparisonRow>
measureLane(Lane& lane,
            const ComparisonRow& base,
            const GroundTruthSurface& truth,
            const MappedViews& mapped,
            double tolerance_m,
            const MappingErrorRegion* region,
            const MethodTimes& ms,
            double ra_divisor,
            std::pair<std::size_t, std::size_t>& planar_counts);

} // namespace detail
} // namespace planar_grid
