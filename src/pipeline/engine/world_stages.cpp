// SPDX-License-Identifier: BSD-3-Clause
#include <planar_grid/core/byte_io.h>
#include <planar_grid/core/exceptions.h>
#include <planar_grid/filters/fast_voxel_grid.h>
#include <planar_grid/map/plane_association.h>

#include <pcl/common/transforms.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <unordered_map>

#include "stages.h"

namespace planar_grid {
namespace stages {

namespace {

class TransformToWorldStage : public Stage {
public:
  bool isFrameLocal() const override { return true; }

  void process(Frame& frame, PipelineState& /*state*/) override
  {
    hasPoints(frame, "transform_to_world"); // an empty cloud moves as well
    if (!frame.has_pose)
      throw Exception("stage 'transform_to_world': frame " + frame.name
                      + " has no pose");
    if (frame.cloud_in_world_frame)
      throw Exception("stage 'transform_to_world': the cloud of frame " + frame.name
                      + " is already in the world frame (stage listed twice?)");
    Frame::Cloud::Ptr out(new Frame::Cloud);
    // PCL warns about an empty cloud's zero width; there is nothing to move.
    if (!frame.cloud->empty())
      pcl::transformPointCloud(*frame.cloud, *out,
                               frame.world_T_camera.cast<float>().matrix());
    // Keep the sensor pose with the cloud, where PCL clouds carry it.
    out->sensor_origin_ << frame.world_T_camera.translation().cast<float>(), 1.0f;
    out->sensor_orientation_ =
      Eigen::Quaternionf(frame.world_T_camera.rotation().cast<float>());
    frame.cloud = out;
    frame.cloud_in_world_frame = true;
    // The later stages take points out of the working cloud (in place when it is
    // organized): the map's ray casting keeps its own copy of what was measured.
    if (frame.disparity.empty())
      frame.measured_cloud.reset(new Frame::Cloud(*out));
  }
};

/** The accumulate stage's parameters: its voxel grid, and the plane association it
 * builds from two of them (associationCriteria()). */
struct AccumulateParams {
  double leaf_size_m{0.1};
  int downsample_every_n_frames{5};
  double plane_merge_angle_rad{PlaneAssociationCriteria{}.eps_angle_rad};
  double plane_merge_distance_m{0.2};
  double window_radius_m{0.0};
};

const ParamDeclarations<AccumulateParams>&
accumulateParamDeclarations()
{
  using P = AccumulateParams;
  static const ParamDeclarations<P> table = {
    declareReal<P>(
      "leaf_size_m", [](auto& p) -> auto& { return p.leaf_size_m; },
      ParamRange::closed(0.0, 10.0), "m",
      "Voxel edge of the accumulated cloud; 0 keeps every point.")
      .scalesWithCellSize(),
    declareInteger<P>(
      "downsample_every_n_frames",
      [](auto& p) -> auto& { return p.downsample_every_n_frames; },
      ParamRange::closed(1, 100000), "",
      "How often the accumulated cloud is downsampled."),
    declareReal<P>(
      "plane_merge_angle_rad", [](auto& p) -> auto& { return p.plane_merge_angle_rad; },
      ParamRange::closed(0.0, 1.5708), "rad",
      "A frame's plane joins a run-wide plane whose normal is this close..."),
    declareReal<P>(
      "plane_merge_distance_m",
      [](auto& p) -> auto& { return p.plane_merge_distance_m; },
      ParamRange::closed(0.0, 10.0), "m",
      "... and whose offset d is this close; else it starts a new one (the pipeline's "
      "value, for this offset distance; PlaneAssociationCriteria's 0.15 m default is "
      "for its evidence distance)."),
    declareReal<P>(
      "window_radius_m", [](auto& p) -> auto& { return p.window_radius_m; },
      ParamRange::closed(0.0, 1e6), "m",
      "Rolling window of the accumulated clouds: at each downsampling only the points "
      "within window_radius_m of the sensor in x and y (world z up) are kept, as "
      "map_integration's window_radius_m keeps the map's; 0 keeps everything."),
  };
  return table;
}

class AccumulateStage : public Stage {
public:
  explicit AccumulateStage(const AccumulateParams& p) :
      params_(p), leaf_size_m_(p.leaf_size_m), every_(p.downsample_every_n_frames),
      window_radius_m_(p.window_radius_m),
      association_(
        associationCriteria(p.plane_merge_angle_rad, p.plane_merge_distance_m))
  {}

  void getParameters(ParamValues& v) const override
  {
    reportParams(accumulateParamDeclarations(), params_, v);
  }

  void process(Frame& frame, PipelineState& state) override
  {
    if (!frame.cloud_in_world_frame)
      throw Exception("stage 'accumulate' needs world-frame clouds: put "
                      "'transform_to_world' before it");
    // All terrain (an open road) leaves no point, and is no warning. A frame without
    // points goes on: it counts towards the downsampling like any other.
    if (!(frame.has_ground && frame.cloud && countValidPoints(*frame.cloud) == 0))
      hasPoints(frame, "accumulate");
    auto& world = *state.world_cloud;
    // Grown geometrically, not to the exact size: an exact reserve would copy the
    // whole accumulated cloud on every frame.
    if (world.points.capacity() < world.size() + frame.cloud->size())
      world.reserve(std::max(world.size() + frame.cloud->size(), 2 * world.size()));
    for (const auto& p : frame.cloud->points)
      if (std::isfinite(p.x) && std::isfinite(p.y) && std::isfinite(p.z))
        world.push_back(p);
    // The planes' inliers, labelled with the run-wide plane they belong to.
    auto& planes = *state.plane_cloud;
    std::vector<int> run_wide_id(frame.planes.size(), -1);
    for (std::size_t k = 0; k < frame.planes.size(); ++k) {
      const auto& plane = frame.planes[k];
      if (plane.model_coefficients.values.size() != 4)
        continue;
      const auto id = static_cast<std::uint32_t>(
        associatePlane(Eigen::Vector4f(plane.model_coefficients.values.data()),
                       plane.inliers.indices.size(), state));
      run_wide_id[k] = static_cast<int>(id);
      for (const auto i : plane.inliers.indices) {
        const auto& p = (*frame.cloud)[static_cast<std::size_t>(i)];
        pcl::PointXYZL q;
        q.getVector3fMap() = p.getVector3fMap();
        q.label = id;
        planes.push_back(q);
      }
    }
    // The frame's cells, relabelled with the run-wide plane ids, unless a map merges
    // them across frames (map_integration).
    for (auto cuboid : state.map ? PlanarCuboids() : frame.cuboids) {
      const auto k = static_cast<std::size_t>(cuboid.plane_id);
      if (cuboid.plane_id >= 0)
        cuboid.plane_id = k < run_wide_id.size() ? run_wide_id[k] : -1;
      state.cuboids.push_back(cuboid);
    }
    if (++frames_since_downsample_ >= every_) {
      if (window_radius_m_ > 0.0)
        cropToWindow(frame.world_T_camera.translation(), state);
      downsample(state);
    }
  }

  void finish(PipelineState& state) override
  {
    if (frames_since_downsample_ > 0)
      downsample(state);
  }

  /** The frames since the last downsampling (the clouds are in PipelineState). */
  void saveState(std::vector<std::uint8_t>& bytes) const override
  {
    ByteWriter(bytes).put(static_cast<std::int32_t>(frames_since_downsample_));
  }

  void loadState(const std::uint8_t* data, std::size_t size) override
  {
    ByteReader r(data, size, "checkpoint: accumulate state");
    const auto frames = r.get<std::int32_t>();
    if (frames < 0 || r.remaining() != 0)
      r.fail("invalid state");
    frames_since_downsample_ = frames;
    sampled_cloud_ = nullptr; // the plane cloud was loaded: its leaves are rebuilt
  }

private:
  /** The accumulate stage's association criteria: normals within
   * plane_merge_angle_rad in either orientation, offsets d within
   * plane_merge_distance_m. */
  static PlaneAssociationCriteria associationCriteria(double plane_merge_angle_rad,
                                                      double plane_merge_distance_m)
  {
    PlaneAssociationCriteria criteria;
    criteria.eps_angle_rad = plane_merge_angle_rad;
    criteria.distance_threshold_m = plane_merge_distance_m;
    criteria.orientation = PlaneOrientation::EITHER;
    criteria.distance = PlaneDistance::OFFSET;
    return criteria;
  }

  /** The run-wide plane with the same coefficients within tolerance (the nearest
   * offset, the lowest id on a tie), updated by the inlier-weighted mean; a new one
   * when none matches. Returns its id. */
  std::size_t associatePlane(const Eigen::Vector4f& c,
                             std::size_t inliers,
                             PipelineState& state) const
  {
    const std::ptrdiff_t found = association_.findBest(
      state.plane_models.size(),
      [&state](std::size_t k) { return PlaneObservation{state.plane_models[k]}; },
      PlaneObservation{c});
    if (found < 0) {
      state.plane_models.push_back(c);
      state.plane_inlier_counts.push_back(inliers);
      return state.plane_models.size() - 1;
    }
    const auto best = static_cast<std::size_t>(found);
    state.plane_models[best] = averageModelCoefficients(
      state.plane_models[best], static_cast<float>(state.plane_inlier_counts[best]), c,
      static_cast<float>(inliers));
    state.plane_inlier_counts[best] += inliers;
    return best;
  }

  /** Drops the world cloud's and the plane cloud's points outside the box of
   * half-size window_radius_m around the sensor in x and y (every height), the
   * map_integration stage's rolling window. */
  void cropToWindow(const Eigen::Vector3d& sensor, PipelineState& state)
  {
    const double r = window_radius_m_;
    const auto outside = [&](const auto& p) {
      return !(std::abs(p.x - sensor.x()) <= r && std::abs(p.y - sensor.y()) <= r);
    };
    auto& world = state.world_cloud->points;
    world.erase(std::remove_if(world.begin(), world.end(), outside), world.end());
    state.world_cloud->width = static_cast<std::uint32_t>(world.size());
    state.world_cloud->height = 1;
    auto& planes = state.plane_cloud->points;
    planes.erase(std::remove_if(planes.begin(), planes.end(), outside), planes.end());
    state.plane_cloud->width = static_cast<std::uint32_t>(planes.size());
    state.plane_cloud->height = 1;
    sampled_cloud_ = nullptr; // the points moved: the leaves are rebuilt
  }

  /** A voxel of the plane cloud's sampling: floor(p / leaf_size_m) per axis. */
  struct Leaf {
    std::int32_t x, y, z;
    bool operator==(const Leaf& o) const { return x == o.x && y == o.y && z == o.z; }
  };
  struct LeafHash {
    std::size_t operator()(const Leaf& l) const
    {
      return static_cast<std::size_t>(
        (static_cast<std::uint64_t>(static_cast<std::uint32_t>(l.x)) * 73856093U)
        ^ (static_cast<std::uint64_t>(static_cast<std::uint32_t>(l.y)) * 19349669U)
        ^ (static_cast<std::uint64_t>(static_cast<std::uint32_t>(l.z)) * 83492791U));
    }
  };

  /** Keeps, per voxel of leaf_size_m, the plane cloud's point nearest the voxel's
   * centre (the first one on a tie; labels are not averaged), as
   * pcl::UniformSampling with the leaf size as its radius does over the whole cloud,
   * but visiting only the points added since the last call: the points kept then
   * hold their voxels (each the nearest of all the points seen there), so a new
   * point only replaces its voxel's point when it is nearer. The kept points stay in
   * the order their voxels were first seen. */
  void samplePlaneCloud(pcl::PointCloud<pcl::PointXYZL>& cloud)
  {
    // single precision as pcl::UniformSampling computes the voxels and the distances
    const auto leaf = static_cast<float>(leaf_size_m_);
    const float inverse = 1.0f / leaf;
    if (sampled_cloud_ != &cloud || sampled_points_ > cloud.size()) {
      plane_leaves_.clear();
      sampled_points_ = 0;
    }
    std::size_t kept = sampled_points_;
    for (std::size_t i = sampled_points_; i < cloud.size(); ++i) {
      const pcl::PointXYZL p = cloud[i];
      if (!std::isfinite(p.x) || !std::isfinite(p.y) || !std::isfinite(p.z))
        continue;
      const Eigen::Array3f scaled = p.getArray3fMap() * inverse;
      if (!(scaled.abs() < 2.0e9f).all())
        continue; // beyond the voxel indices (1e7 m at a 5 mm leaf)
      const Eigen::Array3f cell = scaled.floor();
      const Leaf key{static_cast<std::int32_t>(cell.x()),
                     static_cast<std::int32_t>(cell.y()),
                     static_cast<std::int32_t>(cell.z())};
      const auto [it, added] =
        plane_leaves_.emplace(key, static_cast<std::uint32_t>(kept));
      if (added) {
        cloud[kept++] = p;
        continue;
      }
      Eigen::Vector4f centre = Eigen::Vector4f::Zero();
      centre.head<3>() = ((cell + 0.5f) * leaf).matrix();
      pcl::PointXYZL& held = cloud[it->second];
      if ((p.getVector4fMap() - centre).squaredNorm()
          < (held.getVector4fMap() - centre).squaredNorm())
        held = p;
    }
    cloud.resize(kept);
    cloud.is_dense = true;
    sampled_cloud_ = &cloud;
    sampled_points_ = kept;
  }

  void downsample(PipelineState& state)
  {
    frames_since_downsample_ = 0;
    if (leaf_size_m_ <= 0.0 || state.world_cloud->empty())
      return;
    FastVoxelGrid<pcl::PointXYZI> grid;
    const auto leaf = static_cast<float>(leaf_size_m_);
    grid.setLeafSize(leaf, leaf, leaf);
    grid.setInputCloud(state.world_cloud);
    Frame::Cloud::Ptr out(new Frame::Cloud);
    grid.filter(*out);
    state.world_cloud = out;
    // Labels must not be averaged: keep the point nearest each voxel's centre.
    samplePlaneCloud(*state.plane_cloud);
  }

  AccumulateParams params_;
  double leaf_size_m_;
  int every_;
  double window_radius_m_;
  PlaneAssociation association_;
  int frames_since_downsample_{0};
  /** The plane cloud's voxels and the index of the point each keeps, valid for the
   * first sampled_points_ points of the cloud at sampled_cloud_ (null: rebuilt at the
   * next sampling, after a checkpoint's cloud or a crop). */
  std::unordered_map<Leaf, std::uint32_t, LeafHash> plane_leaves_;
  const pcl::PointCloud<pcl::PointXYZL>* sampled_cloud_{nullptr};
  std::size_t sampled_points_{0};
};

} // namespace

StageInfo
transformToWorldInfo()
{
  StageInfo info;
  info.type = "transform_to_world";
  info.description =
    "Moves the working cloud from the camera frame to the world frame with the "
    "frame's "
    "pose (pcl::transformPointCloud); keeps the sensor origin and orientation.";
  info.needs_poses = true;
  info.create = [](const ParamValues&) -> std::unique_ptr<Stage> {
    return std::make_unique<TransformToWorldStage>();
  };
  return info;
}

StageInfo
accumulateInfo()
{
  StageInfo info;
  info.type = "accumulate";
  info.description = "Appends each world-frame cloud to the accumulated world cloud, "
                     "voxel-downsampled "
                     "(FastVoxelGrid, pcl::VoxelGrid's output) every few frames so "
                     "memory stays bounded by the "
                     "scene, not the run.";
  info.params = paramSpecs(accumulateParamDeclarations());
  info.create = [](const ParamValues& v) -> std::unique_ptr<Stage> {
    AccumulateParams p;
    assignParams(accumulateParamDeclarations(), v, p);
    return std::make_unique<AccumulateStage>(p);
  };
  return info;
}

} // namespace stages
} // namespace planar_grid
