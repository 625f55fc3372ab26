// SPDX-License-Identifier: BSD-3-Clause
// The declaration of every SACMultiPlaneSegmentationParams member: the
// multi_plane_segmentation stage and the stage reference are made from it.
#include <planar_grid/core/exceptions.h>
#include <planar_grid/segmentation/sac_multi_plane_segmentation_params.h>
#include <planar_grid/segmentation/sac_multi_plane_segmentation_ranges.h>

#include <algorithm>
#include <iterator>
#include <string>
#include <vector>

namespace planar_grid {

namespace {

using Params = SACMultiPlaneSegmentationParams;

/** The names of the sample consensus estimators, in SACMethod's order. */
const std::vector<std::string>&
sacMethodNames()
{
  static const std::vector<std::string> names{"ransac", "msac", "prosac"};
  return names;
}

/** The hypotheses' parameters: eq. 11, the sample consensus, the refinement and the
 * merge of near-duplicate planes. */
ParamDeclarations<Params>
hypothesisDeclarations()
{
  namespace ranges = sac_multi_plane_segmentation_ranges;
  using Scaling = CellSizeScaling;
  return {
    declareReal<Params>(
      "distance_threshold_m", [](auto& p) -> auto& { return p.distance_threshold_m; },
      ranges::DISTANCE_THRESHOLD, "m",
      "d_T of eq. 11: dense points this close to a plane are its inliers."),
    declareFlag<Params>(
      "depth_noise_along_sight",
      [](auto& p) -> auto& { return p.depth_noise_along_sight; },
      "With depth_noise_disparity_px: a point is an inlier within max(d_T, Delta z "
      "|n . u|), Delta z projected on the plane's normal n from the point's line of "
      "sight u (stereo displaces points along it): a road seen at a grazing angle "
      "keeps about d_T and no longer takes what stands on it at range."),
    declareReal<Params>(
      "sample_distance_threshold_m",
      [](auto& p) -> auto& { return p.sample_distance_threshold_m; },
      ranges::SAMPLE_DISTANCE_THRESHOLD, "m",
      "RANSAC inlier threshold on the sample (stereo features are noisier)."),
    declareInteger<Params>(
      "max_planes", [](auto& p) -> auto& { return p.max_planes; }, ranges::MAX_PLANES,
      "", "Most planes per frame."),
    declareInteger<Params>(
      "min_inliers", [](auto& p) -> auto& { return p.min_inliers; },
      ranges::MIN_INLIERS, "", "A plane needs at least this many dense inliers.")
      .scalesWithCellSize(Scaling::POINTS_PER_AREA),
    declareInteger<Params>(
      "min_sample_inliers", [](auto& p) -> auto& { return p.min_sample_inliers; },
      ranges::MIN_SAMPLE_INLIERS, "",
      "A hypothesis needs at least this many sample inliers."),
    declareReal<Params>(
      "min_remaining_fraction",
      [](auto& p) -> auto& { return p.min_remaining_fraction; },
      ranges::MIN_REMAINING_FRACTION, "",
      "Stop when less than this fraction of the sample remains."),
    declareInteger<Params>(
      "max_iterations", [](auto& p) -> auto& { return p.max_iterations; },
      ranges::MAX_ITERATIONS, "", "RANSAC iterations per plane."),
    declareReal<Params>(
      "probability", [](auto& p) -> auto& { return p.probability; },
      ranges::PROBABILITY, "",
      "The probability of drawing at least one outlier-free sample: the sample "
      "consensus stops once its best hypothesis makes that likely."),
    declareChoice<Params>(
      "method", [](auto& p) -> auto& { return p.method; }, sacMethodNames(),
      sacMethodName, sacMethodFromName, "PCL sample consensus estimator."),
    declareFlag<Params>(
      "optimize_coefficients", [](auto& p) -> auto& { return p.optimize_coefficients; },
      "Least-squares refit of each plane on its dense inliers."),
    declareFlag<Params>(
      "dense_hypothesis", [](auto& p) -> auto& { return p.dense_hypothesis; },
      "Each round also hypothesises a plane from a dense subsample; the one with more "
      "inliers is kept."),
    declareInteger<Params>(
      "lo_iterations", [](auto& p) -> auto& { return p.lo_iterations; },
      ranges::LO_ITERATIONS, "",
      "Local optimisation (LO-RANSAC) samples per plane; 0 = off."),
    declareFlag<Params>(
      "merge_planes", [](auto& p) -> auto& { return p.merge_planes; },
      "Merge near-duplicate planes."),
    declareReal<Params>(
      "merge_angle_rad", [](auto& p) -> auto& { return p.merge_angle_rad; },
      ranges::MERGE_ANGLE_THRESHOLD, "rad",
      "Planes whose normals differ less than this may merge."),
    declareReal<Params>(
      "merge_distance_m", [](auto& p) -> auto& { return p.merge_distance_m; },
      ranges::MERGE_DISTANCE_THRESHOLD, "m",
      "... and whose offsets differ less than this."),
    declareInteger<Params>(
      "seed", [](auto& p) -> auto& { return p.seed; },
      ParamRange::closed(0, 2147483647), "",
      "Random seed: the same seed gives the same planes."),
    declareInteger<Params>(
      "max_sample_size", [](auto& p) -> auto& { return p.max_sample_size; },
      ranges::MAX_SAMPLE_SIZE, "",
      "Hypotheses from the cloud (no sample cloud set; the stage's sample: cloud) "
      "come from a seeded subsample of this many of its points."),
  };
}

/** The dense inliers' tests: visibility, sensor distance and height, clusters, shells,
 * the inlier-only points and the normal test. */
ParamDeclarations<Params>
inlierTestDeclarations()
{
  namespace ranges = sac_multi_plane_segmentation_ranges;
  using Scaling = CellSizeScaling;
  return {
    declareReal<Params>(
      "max_visibility_conflict_ratio",
      [](auto& p) -> auto& { return p.max_visibility_conflict_ratio; },
      ranges::MAX_VISIBILITY_CONFLICT_RATIO, "",
      "Visibility test: where, around a 3 x 3 cell neighbourhood of a plane's "
      "footprint, more than this many points per inlier are seen through the plane or "
      "hide it from the camera (a slab through a tree's canopy), those inliers leave "
      "the plane; 0 = no test."),
    declareReal<Params>(
      "visibility_margin_m", [](auto& p) -> auto& { return p.visibility_margin_m; },
      ranges::VISIBILITY_MARGIN, "m",
      "A point conflicts with a plane only this much (plus its eq. 11 threshold) off "
      "it."),
    declareReal<Params>(
      "visibility_cell_m", [](auto& p) -> auto& { return p.visibility_cell_m; },
      ranges::VISIBILITY_CELL, "m",
      "Cell edge of a plane's footprint in the visibility and the shell tests."),
    declareReal<Params>(
      "min_sensor_distance_m", [](auto& p) -> auto& { return p.min_sensor_distance_m; },
      ranges::MIN_SENSOR_DISTANCE, "m",
      "Sensor plane test: a plane passing closer than this to the sensor is dropped "
      "and its inliers go to no later plane (it contains the lines of sight, along "
      "which stereo smears every object: a vertical sheet through a tree trunk, a "
      "horizontal one at the camera's height); 0 = no test."),
    declareReal<Params>(
      "min_sensor_height_m", [](auto& p) -> auto& { return p.min_sensor_height_m; },
      ranges::MIN_TERRAIN_SENSOR_HEIGHT, "m",
      "The normal and cluster tests spare a level plane as terrain only when the "
      "sensor lies more than this above it (a level plane just below the camera is no "
      "ground: spared, it takes a stripe of every wall at its height); 0: every level "
      "plane below the sensor."),
    declareReal<Params>(
      "max_terrain_below_ratio",
      [](auto& p) -> auto& { return p.max_terrain_below_ratio; },
      ranges::MAX_TERRAIN_BELOW_RATIO, "",
      "The normal and cluster tests spare a level plane as terrain only when the "
      "frame's points more than 0.3 m below it, in the 0.3 m squares its inliers cover "
      "(seen along the up axis), number at most this many per inlier: a slab through "
      "car bonnets, a table top or a plane in mid-air has the road, the floor or the "
      "walls' lower parts under it and is tested like a wall, so the ground removal "
      "does not take what stands under it; 1 = no test."),
    declareInteger<Params>(
      "min_cluster_size", [](auto& p) -> auto& { return p.min_cluster_size; },
      ranges::MIN_CLUSTER_SIZE, "",
      "Cluster test: the inliers of each connected cluster of a plane's footprint "
      "(cluster_cell_m cells, a one-cell gap bridged) holding fewer than this many "
      "leave the plane (a plane through separate trunks, or slicing car bodies); 0 = "
      "no test.")
      .scalesWithCellSize(Scaling::POINTS_PER_AREA),
    declareReal<Params>(
      "cluster_cell_m", [](auto& p) -> auto& { return p.cluster_cell_m; },
      ranges::CLUSTER_CELL, "m",
      "Footprint cell edge of the cluster test (at least the voxel edge of a "
      "voxelised cloud).")
      .scalesWithCellSize(Scaling::CELL_SIZE),
    declareReal<Params>(
      "max_shell_ratio", [](auto& p) -> auto& { return p.max_shell_ratio; },
      ranges::MAX_SHELL_RATIO, "",
      "Shell test: where, around a 3 x 3 cell neighbourhood of a plane's footprint, "
      "twice the smaller of the two sides' counts of points just beyond the eq. 11 "
      "threshold t (between t and t + max(t, shell_width_m) off the plane) exceeds "
      "this many per inlier (a slab through a canopy, a stripe across a facade or a "
      "car), those inliers leave the plane; 0 = no test."),
    declareReal<Params>(
      "shell_width_m", [](auto& p) -> auto& { return p.shell_width_m; },
      ranges::SHELL_WIDTH, "m",
      "Smallest width of the shell test's shell (a voxelised cloud's surface points "
      "lie in layers one voxel apart).")
      .scalesWithCellSize(Scaling::CELL_SIZE),
    declareFlag<Params>(
      "count_inlier_only_points",
      [](auto& p) -> auto& { return p.count_inlier_only_points; },
      "The points beyond depth_error_filter's cell bound (kept by its "
      "max_plane_depth_error_m) count towards min_inliers, so that a plane the key "
      "features make may stand on them alone; false: a plane needs min_inliers nearer "
      "points, which they only extend."),
    declareReal<Params>(
      "inlier_only_distance_threshold_m",
      [](auto& p) -> auto& { return p.inlier_only_distance_threshold_m; },
      ranges::INLIER_ONLY_DISTANCE_THRESHOLD, "m",
      "Those points join a plane within the smaller of this and their eq. 11 "
      "threshold (a planar cell is as thick as its inliers' spread); 0: eq. 11's."),
    declareReal<Params>(
      "max_normal_angle_rad", [](auto& p) -> auto& { return p.max_normal_angle_rad; },
      ranges::MAX_NORMAL_ANGLE, "rad",
      "Normal test: a point is an inlier only when its surface normal (fitted to the "
      "points of the 3 x 3 x 3 normal_cell_m cells around it, or to the disparities "
      "around its pixel, normal_source) lies within this angle of the plane's normal; "
      "a point without a normal (too few neighbours) is judged by distance alone (a "
      "canopy's or a pole's points scatter in normal, a wall's agree). Terrain planes "
      "(within 0.3 rad of level, below the sensor) are spared. 0 = no test."),
    declareReal<Params>(
      "normal_cell_m", [](auto& p) -> auto& { return p.normal_cell_m; },
      ranges::NORMAL_CELL, "m",
      "Cell edge of the normal estimation (about twice the voxel edge: a stereo "
      "surface is as thick as its depth noise).")
      .scalesWithCellSize(Scaling::LENGTH),
    declareReal<Params>(
      "min_normal_agreement", [](auto& p) -> auto& { return p.min_normal_agreement; },
      ranges::MIN_NORMAL_AGREEMENT, "",
      "Normal test: a hypothesis whose inliers by distance agree with its normal less "
      "often than this is dropped (a plane through vegetation, clutter, or across a "
      "surface at an angle); 0 = no test."),
  };
}

ParamDeclarations<Params>
makeParamDeclarations()
{
  ParamDeclarations<Params> table = hypothesisDeclarations();
  ParamDeclarations<Params> tests = inlierTestDeclarations();
  table.insert(table.end(), std::make_move_iterator(tests.begin()),
               std::make_move_iterator(tests.end()));
  return table;
}

} // namespace

const std::string&
sacMethodName(SACMethod method)
{
  return sacMethodNames()[static_cast<std::size_t>(method)];
}

SACMethod
sacMethodFromName(const std::string& name)
{
  const auto& names = sacMethodNames();
  const auto it = std::find(names.begin(), names.end(), name);
  if (it == names.end())
    throw Exception("Unknown sample consensus method '" + name
                    + "' (ransac, msac, prosac)");
  return static_cast<SACMethod>(it - names.begin());
}

const ParamDeclarations<SACMultiPlaneSegmentationParams>&
sacMultiPlaneSegmentationParamDeclarations()
{
  static const ParamDeclarations<Params> table = makeParamDeclarations();
  return table;
}

} // namespace planar_grid
