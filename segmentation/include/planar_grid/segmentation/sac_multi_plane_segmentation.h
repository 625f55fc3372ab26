// SPDX-License-Identifier: BSD-3-Clause
#pragma once

#include <planar_grid/core/param_range.h>
#include <planar_grid/segmentation/planar_segment.h>
#include <planar_grid/segmentation/plane_test_counts.h>
#include <planar_grid/segmentation/sac_multi_plane_segmentation_params.h>
#include <planar_grid/segmentation/sac_multi_plane_segmentation_ranges.h>

#include <pcl/ModelCoefficients.h>
#include <pcl/PointIndices.h>
#include <pcl/pcl_base.h>
#include <pcl/pcl_macros.h>
#include <pcl/point_cloud.h>

#include <Eigen/Core>
#include <Eigen/StdVector>

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <functional>
#include <memory>
#include <random>
#include <string>
#include <utility>
#include <vector>

namespace pcl {
struct Normal;
} // namespace pcl

namespace planar_grid {

namespace detail {
struct DensePoints;
} // namespace detail

/** \brief Multi-plane segmentation by repeated sample consensus (the multi-RANSAC of
 * Sec. III-C of the paper ("Efficient Planar Surface-Based 3D Mapping Method for Mobile
 * Robots Using Stereo Vision"), eqs. 1-3) with the dense inlier selection of Sec.
 * III-F, eq. 11.
 *
 * Plane hypotheses come from a sparse sample cloud (the 3D key feature points, as in
 * the paper) when setSampleCloud() is given, else from a seeded random subsample of at
 * most getMaxSampleSize() finite points of the input cloud (within the indices). Each
 * round runs pcl::SampleConsensusModelPlane under the chosen SACMethod on the remaining
 * sample points; when optimize_coefficients is set, re-estimates the hypothesis by
 * a plain RANSAC at d_T (struct of arrays, early-exit counting, seeded; PCL's adaptive
 * iteration count) on a seeded subsample (<= 5000) of the unassigned
 * dense points within max(sample_distance_threshold, 10 d_T) of it (the features are
 * noisy). With the dense hypothesis (default) the same RANSAC on a subsample of all
 * unassigned points proposes a second plane, and the one with more eq. 11 inliers is
 * kept; a local optimisation (LO-RANSAC, default 50 samples) then moves it to more
 * inliers where it can. The round selects the dense inliers of the input cloud (eq. 11,
 * distance <= d_T) that no earlier plane took, optionally refits the plane to them by
 * PCA and reselects, then removes the plane's sample and dense inliers. Planes with
 * fewer than min_inliers dense inliers are dropped (their sample inliers are still
 * removed). The loop stops after max_planes planes, when the sample consensus finds
 * fewer than min_sample_inliers, when fewer than min_remaining_fraction of the sample
 * points remain, or after 3 max_planes rounds. Near-duplicate planes are then merged.
 *
 * Defaults: the pipeline's tuned values (SACMultiPlaneSegmentationParams). Beyond the
 * paper they turn on the normal test (setMaxNormalAngle() 0.5 rad with
 * setMinNormalAgreement() 0.35, normals estimated on a 0.2 m grid unless given) and
 * draw the hypotheses at 0.1 m on the noisier sample cloud; setMaxNormalAngle(0)
 * gives the paper's distance-only eq. 11.
 *
 * Determinism: PCL's estimators are built with random = false (fixed seed 12345);
 * setSeed() seeds a std::mt19937 that draws the input subsample and shuffles the sample
 * indices before every round, so the same input and seed give the same output.
 *
 * Empty or degenerate input (no input, empty cloud, only NaNs, fewer than 3 points,
 * colinear points) or invalid parameters give an empty output and a PCL_ERROR or
 * PCL_WARN; segment() never throws for bad data. Degenerate minimal samples
 * (coincident or colinear points, e.g. duplicated features) are rejected silently
 * (PCL_DEBUG), and the loop stops when the remaining sample points are colinear.
 * \ingroup segmentation */
template <typename PointT>
class SACMultiPlaneSegmentation : public pcl::PCLBase<PointT> {
public:
  /** \brief Shared pointer to a SACMultiPlaneSegmentation. */
  using Ptr = std::shared_ptr<SACMultiPlaneSegmentation<PointT>>;
  /** \brief Shared pointer to a const SACMultiPlaneSegmentation. */
  using ConstPtr = std::shared_ptr<const SACMultiPlaneSegmentation<PointT>>;
  /** \brief The input cloud type. */
  using PointCloud = pcl::PointCloud<PointT>;
  /** \brief Shared pointer to an input cloud. */
  using PointCloudPtr = typename PointCloud::Ptr;
  /** \brief Shared pointer to a const input cloud. */
  using PointCloudConstPtr = typename PointCloud::ConstPtr;
  /** \brief Surface normals, one per input point (pcl::Normal). */
  using NormalCloudConstPtr = std::shared_ptr<const pcl::PointCloud<pcl::Normal>>;

  /** \brief The parameters the pipeline sets (SACMultiPlaneSegmentationParams). */
  using Params = SACMultiPlaneSegmentationParams;

  /** \brief Each parameter's one declaration (key, range, unit, meaning): the
   * multi_plane_segmentation stage and its reference are made from it.
   * \return sacMultiPlaneSegmentationParamDeclarations() */
  static const ParamDeclarations<Params>& getParamDeclarations()
  {
    return sacMultiPlaneSegmentationParamDeclarations();
  }

  /** \brief A segmentation with the default parameters. */
  SACMultiPlaneSegmentation() = default;
  /** \brief A segmentation with \a params (checked by segment()). */
  explicit SACMultiPlaneSegmentation(const Params& params) : params_(params) {}
  ~SACMultiPlaneSegmentation() override = default;

  /** \brief Sets the parameters of Params at once (checked by segment()). */
  void setParams(const Params& params) { params_ = params; }
  /** \brief The parameters of Params. */
  const Params& getParams() const { return params_; }

  /** \brief Sets the sparse cloud the plane hypotheses are drawn from (e.g. stereo
   * feature points in the input cloud's frame); nullptr (the default) hypothesises
   * from a subsample of the input cloud. All its finite points are used.
   * \param[in] cloud the sample cloud */
  void setSampleCloud(const PointCloudConstPtr& cloud) { sample_cloud_ = cloud; }
  /** \brief Returns the sample cloud (nullptr when none is set). */
  PointCloudConstPtr getSampleCloud() const { return sample_cloud_; }

  /** \brief Sets the inlier-only points: points of the input cloud that may join a
   * plane as eq. 11 inliers, and count towards setMinInliers(), but take no part in
   * making planes: they are left out of the cloud subsample the hypotheses are drawn
   * from without a sample cloud, the dense hypothesis, the local refinement and the
   * LO-RANSAC, so that a plane always comes from the sample cloud or the other input
   * points. For stereo points beyond the range where they are too noisy to make
   * planes or cells of their own, which may still extend the planes the nearer points
   * and the key features support. An index given here is inlier-only even when it is
   * also in the input indices; indices outside the cloud are ignored.
   * \param[in] indices indices into the input cloud; nullptr or empty (the default):
   * none */
  void setInlierOnlyIndices(const pcl::IndicesConstPtr& indices)
  {
    inlier_only_indices_ = indices;
  }
  /** \brief Returns the inlier-only indices (nullptr when none are set). */
  pcl::IndicesConstPtr getInlierOnlyIndices() const { return inlier_only_indices_; }

  /** \brief Sets whether the inlier-only points count towards setMinInliers(): with
   * true (the default) a plane the sample cloud makes may stand on inlier-only points
   * alone; with false it needs min_inliers of the other points, which the inlier-only
   * points then only extend.
   * \param[in] count whether they count */
  void setCountInlierOnlyPoints(bool count)
  {
    params_.count_inlier_only_points = count;
  }
  /** \brief Returns whether the inlier-only points count towards min_inliers. */
  bool getCountInlierOnlyPoints() const { return params_.count_inlier_only_points; }

  /** \brief Sets the largest point-to-plane distance of an inlier-only point: they join
   * a plane within the smaller of it and their eq. 11 threshold (with the depth
   * noise, setDepthNoiseCoefficient(), the latter exceeds 0.3 m beyond 15 m of a
   * Karlsruhe-like rig, and a planar cell is as thick as its inliers' spread).
   * \param[in] distance_m in meters, in
   * sac_multi_plane_segmentation_ranges::INLIER_ONLY_DISTANCE_THRESHOLD (default 0: eq.
   * 11's threshold) */
  void setInlierOnlyDistanceThreshold(double distance_m)
  {
    params_.inlier_only_distance_threshold_m = distance_m;
  }
  /** \brief Returns the inlier-only points' distance threshold, in meters (0: eq.
   * 11's). */
  double getInlierOnlyDistanceThreshold() const
  {
    return params_.inlier_only_distance_threshold_m;
  }

  /** \brief Sets d_T of eq. 11, the largest point-to-plane distance of a dense inlier.
   * \param[in] distance_threshold_m in meters, in
   * sac_multi_plane_segmentation_ranges::DISTANCE_THRESHOLD (default 0.05, the paper's
   * value) */
  void setDistanceThreshold(double distance_threshold_m)
  {
    params_.distance_threshold_m = distance_threshold_m;
  }
  /** \brief Returns d_T of eq. 11, in meters. */
  double getDistanceThreshold() const { return params_.distance_threshold_m; }

  /** \brief Sets the stereo depth noise of the dense points, so that eq. 11's
   * threshold grows with range as the depth error of Sec. III-D does: a dense point at
   * distance r from the input cloud's sensor origin is an inlier within
   * max(d_T, coefficient r^2) of a plane, where coefficient r^2 is the stereo depth
   * error Delta z = z^2 Delta d / (B f) (eq. 4, with r for z). With d_T = 0.05 m, a
   * 0.5 px disparity error and B f = 368 px m (Karlsruhe), the threshold grows beyond
   * d_T from 6 m and is 0.14 m at 10 m. Hypotheses are still drawn and scored at d_T.
   * \param[in] coefficient_per_m Delta d / (B f), in 1/m, in
   * sac_multi_plane_segmentation_ranges::DEPTH_NOISE_COEFFICIENT (default 0: the
   * paper's fixed d_T) */
  void setDepthNoiseCoefficient(double coefficient_per_m)
  {
    depth_noise_coefficient_ = coefficient_per_m;
  }
  /** \brief Returns the depth noise coefficient, in 1/m (0: fixed d_T). */
  double getDepthNoiseCoefficient() const { return depth_noise_coefficient_; }

  /** \brief Sets whether the stereo depth noise (setDepthNoiseCoefficient()) widens
   * eq. 11 by its component along each plane's normal: stereo displaces a point along
   * its line of sight, so a point seen in direction u is an inlier of a plane of normal
   * n within max(d_T, coefficient r^2 |n . u|). A wall facing the sensor keeps the
   * whole depth error; a road seen at a grazing angle keeps about d_T, so that its
   * band no longer takes what stands on it (a guardrail, a hedge) at range.
   * \param[in] along_sight true: projected on the normal; false (default): the whole
   * depth error, whatever the plane */
  void setDepthNoiseAlongSight(bool along_sight)
  {
    params_.depth_noise_along_sight = along_sight;
  }
  /** \brief Returns whether the depth noise is projected on each plane's normal. */
  bool getDepthNoiseAlongSight() const { return params_.depth_noise_along_sight; }

  /** \brief Sets the inlier threshold of the sample consensus on the sample cloud.
   * \param[in] distance_threshold_m in meters, in
   * sac_multi_plane_segmentation_ranges::SAMPLE_DISTANCE_THRESHOLD (default 0.1, twice
   * the default d_T: stereo features are noisier than the dense cloud). It does not
   * follow setDistanceThreshold(); a user who hypothesises from the input cloud itself
   * (no sample cloud) may set it to d_T. */
  void setSampleDistanceThreshold(double distance_threshold_m)
  {
    params_.sample_distance_threshold_m = distance_threshold_m;
  }
  /** \brief Returns the sample consensus threshold, in meters. */
  double getSampleDistanceThreshold() const
  {
    return params_.sample_distance_threshold_m;
  }

  /** \brief Sets the largest number of planes returned (before merging).
   * \param[in] max_planes in sac_multi_plane_segmentation_ranges::MAX_PLANES (default
   * 8) */
  void setMaxPlanes(int max_planes) { params_.max_planes = max_planes; }
  /** \brief Returns the largest number of planes. */
  int getMaxPlanes() const { return params_.max_planes; }

  /** \brief Sets the fewest dense inliers a plane needs to be kept.
   * \param[in] min_inliers in sac_multi_plane_segmentation_ranges::MIN_INLIERS (default
   * 500) */
  void setMinInliers(int min_inliers) { params_.min_inliers = min_inliers; }
  /** \brief Returns the fewest dense inliers of a plane. */
  int getMinInliers() const { return params_.min_inliers; }

  /** \brief Sets the fewest sample inliers a hypothesis needs; fewer ends the loop.
   * \param[in] min_sample_inliers in
   * sac_multi_plane_segmentation_ranges::MIN_SAMPLE_INLIERS (default 15) */
  void setMinSampleInliers(int min_sample_inliers)
  {
    params_.min_sample_inliers = min_sample_inliers;
  }
  /** \brief Returns the fewest sample inliers of a hypothesis. */
  int getMinSampleInliers() const { return params_.min_sample_inliers; }

  /** \brief Sets the remaining fraction of sample points below which the loop stops.
   * \param[in] fraction in sac_multi_plane_segmentation_ranges::MIN_REMAINING_FRACTION
   * (default 0.05) */
  void setMinRemainingFraction(double fraction)
  {
    params_.min_remaining_fraction = fraction;
  }
  /** \brief Returns the remaining-fraction stop criterion, in [0, 1). */
  double getMinRemainingFraction() const { return params_.min_remaining_fraction; }

  /** \brief Sets the sample consensus iteration cap per plane.
   * \param[in] max_iterations in sac_multi_plane_segmentation_ranges::MAX_ITERATIONS
   * (default 1000) */
  void setMaxIterations(int max_iterations) { params_.max_iterations = max_iterations; }
  /** \brief Returns the sample consensus iteration cap per plane. */
  int getMaxIterations() const { return params_.max_iterations; }

  /** \brief Sets the probability of drawing at least one outlier-free sample.
   * \param[in] probability in sac_multi_plane_segmentation_ranges::PROBABILITY (default
   * 0.99) */
  void setProbability(double probability) { params_.probability = probability; }
  /** \brief Returns the sample consensus probability, in (0, 1). */
  double getProbability() const { return params_.probability; }

  /** \brief Sets the sample consensus estimator.
   * \param[in] method RANSAC (default), MSAC or PROSAC */
  void setMethodType(SACMethod method) { params_.method = method; }
  /** \brief Returns the sample consensus estimator. */
  SACMethod getMethodType() const { return params_.method; }

  /** \brief Sets whether each hypothesis is re-estimated on the dense points near it
   * (local RANSAC, see the class description) and each plane refitted (PCA, least
   * squares) to its dense inliers, which are then reselected with the refitted plane.
   * \param[in] optimize default true */
  void setOptimizeCoefficients(bool optimize)
  {
    params_.optimize_coefficients = optimize;
  }
  /** \brief Returns whether planes are refitted to their dense inliers. */
  bool getOptimizeCoefficients() const { return params_.optimize_coefficients; }

  /** \brief Sets whether every round also hypothesises a plane from the dense points:
   * a plain RANSAC at d_T (the same iteration cap and probability) on a seeded
   * subsample (<= 5000) of the unassigned input points. Of it and the sample cloud's
   * hypothesis, the plane with more eq. 11 inliers among the unassigned points is kept.
   * It finds large planes that the sample has few points on (a road with little
   * texture, for stereo features); on Karlsruhe frame 10 (6 planes, seeds 0-3) it
   * raised the eq. 11 coverage from 0.54-0.59 to 0.60-0.61 for ~20 ms CPU, and with
   * the local optimisation to 0.61-0.62 (docs/SEGMENTATION.md).
   * \param[in] dense_hypothesis default true; false hypothesises from the sample only
   * (the paper's feature-only multi-RANSAC) */
  void setDenseHypothesis(bool dense_hypothesis)
  {
    params_.dense_hypothesis = dense_hypothesis;
  }
  /** \brief Returns whether every round also hypothesises from the dense points. */
  bool getDenseHypothesis() const { return params_.dense_hypothesis; }

  /** \brief Sets the iterations of the local optimisation of each kept hypothesis (the
   * LO step of LO-RANSAC, Chum et al. 2003): minimal samples drawn from the plane's
   * eq. 11 inliers, each counted over all unassigned input points; one with more
   * inliers replaces the plane. It runs before the PCA refit.
   * \param[in] lo_iterations in sac_multi_plane_segmentation_ranges::LO_ITERATIONS
   * (default 50; 0 disables it) */
  void setLocalOptimizationIterations(int lo_iterations)
  {
    params_.lo_iterations = lo_iterations;
  }
  /** \brief Returns the local optimisation iterations per plane. */
  int getLocalOptimizationIterations() const { return params_.lo_iterations; }

  /** \brief Sets whether near-duplicate planes are merged (inliers united, refitted).
   * The united inliers are one surface's (e.g. the layers of a road that is not quite
   * planar), but need not all lie within d_T of the refitted plane.
   * \param[in] merge default true */
  void setMergePlanes(bool merge) { params_.merge_planes = merge; }
  /** \brief Returns whether near-duplicate planes are merged. */
  bool getMergePlanes() const { return params_.merge_planes; }

  /** \brief Sets the largest angle between the normals of two planes that merge.
   * \param[in] eps_angle_rad in radians, in
   * sac_multi_plane_segmentation_ranges::MERGE_ANGLE_THRESHOLD (default 0.1) */
  void setMergeAngleThreshold(double eps_angle_rad)
  {
    params_.merge_angle_rad = eps_angle_rad;
  }
  /** \brief Returns the merge angle threshold, in radians. */
  double getMergeAngleThreshold() const { return params_.merge_angle_rad; }

  /** \brief Sets the largest difference of the Hessian offsets d of two planes that
   * merge. \param[in] distance_threshold_m in meters, in
   * sac_multi_plane_segmentation_ranges::MERGE_DISTANCE_THRESHOLD (default 0.1) */
  void setMergeDistanceThreshold(double distance_threshold_m)
  {
    params_.merge_distance_m = distance_threshold_m;
  }
  /** \brief Returns the merge offset threshold, in meters. */
  double getMergeDistanceThreshold() const { return params_.merge_distance_m; }

  /** \brief Sets the visibility test. An opaque surface hides what lies behind it
   * from the sensor. A point conflicts with a plane when it lies off the plane by more
   * than the margin plus its eq. 11 threshold and the line of sight from the input
   * cloud's sensor_origin_ through it meets the plane in a cell of the plane's
   * footprint (setVisibilityCell) that holds an inlier: behind the plane it was seen
   * through the surface, in front of it it hides the surface. A wall, a road or a car's
   * side has next to no conflicts (what stands in front of a wall hides cells that then
   * hold no inlier), while a slab fitted through a volume of scattered points, such as
   * a tree's canopy, has about as many as inliers or more. Where, over a footprint cell
   * and its 8 neighbours, the conflicts outnumber `ratio` x the inliers, the cell's
   * inliers leave the plane (they stay for later planes or the non-planar cells); a
   * plane left with fewer than min_inliers is dropped. Not in the paper, whose planes
   * come from key features alone: it keeps eq. 11 from taking a slab through a volume
   * for a surface. The clouds must be in one sensor's view (one frame).
   * \param[in] ratio in
   * sac_multi_plane_segmentation_ranges::MAX_VISIBILITY_CONFLICT_RATIO (default 0: no
   * test) */
  void setMaxVisibilityConflictRatio(double ratio)
  {
    params_.max_visibility_conflict_ratio = ratio;
  }
  /** \brief Returns the largest ratio of visibility conflicts to inliers of a
   * footprint neighbourhood (0: no test). */
  double getMaxVisibilityConflictRatio() const
  {
    return params_.max_visibility_conflict_ratio;
  }

  /** \brief Sets how far off a plane, beyond its eq. 11 threshold, a point must lie to
   * conflict with it. \param[in] margin_m in meters, in
   * sac_multi_plane_segmentation_ranges::VISIBILITY_MARGIN (default 0.3) */
  void setVisibilityMargin(double margin_m) { params_.visibility_margin_m = margin_m; }
  /** \brief Returns the visibility margin, in meters. */
  double getVisibilityMargin() const { return params_.visibility_margin_m; }

  /** \brief Sets the edge of the square cells of a plane's footprint in the
   * visibility and the shell tests. \param[in] cell_m in meters, in
   * sac_multi_plane_segmentation_ranges::VISIBILITY_CELL (default 0.2) */
  void setVisibilityCell(double cell_m) { params_.visibility_cell_m = cell_m; }
  /** \brief Returns the footprint cell edge of the visibility and the shell tests, in
   * meters. */
  double getVisibilityCell() const { return params_.visibility_cell_m; }

  /** \brief Sets the shell test. A surface's points lie within its eq. 11 threshold t
   * (up to stereo noise), while a plane that cuts through a thicker structure, a slab
   * through a tree's canopy or a horizontal stripe across a facade or a car (a row of
   * key features along a facade spans such a plane), has about as many points just
   * beyond t as within it, on both sides. The shell of a plane is the points lying
   * between t and t + max(t, shell_width) off it (t: each point's own eq. 11
   * threshold) whose orthogonal projection falls in a cell of the plane's footprint
   * (setVisibilityCell), counted apart in front of the plane and behind it. Where,
   * over a footprint cell and its 8 neighbours, twice the smaller of the two counts
   * exceeds `ratio` x the inliers, the cell's inliers leave the plane (they stay for
   * later planes or the non-planar cells); a plane left with fewer than min_inliers is
   * dropped. What stands on a surface or in front of it (a car on the road, a pole in
   * front of a wall) is on one side only and does not count. For a uniform volume or
   * a surface perpendicular to the plane the ratio is about 1 at shell width t; for
   * Gaussian noise whose standard deviation reaches t it is 0.40. Not in the paper.
   * \param[in] ratio shell points per inlier, in
   * sac_multi_plane_segmentation_ranges::MAX_SHELL_RATIO (default 0: no test) */
  void setMaxShellRatio(double ratio) { params_.max_shell_ratio = ratio; }
  /** \brief Returns the largest ratio of shell points to inliers of a footprint
   * neighbourhood (0: no test). */
  double getMaxShellRatio() const { return params_.max_shell_ratio; }

  /** \brief Sets the smallest width of the shell of the shell test: the shell reaches
   * max(t, width) beyond each point's eq. 11 threshold t. On a voxelised cloud the
   * points of a surface lie in layers one voxel apart, so the shell should be at least
   * one voxel wide. \param[in] width_m in meters, in
   * sac_multi_plane_segmentation_ranges::SHELL_WIDTH (default 0.1) */
  void setShellWidth(double width_m) { params_.shell_width_m = width_m; }
  /** \brief Returns the smallest shell width of the shell test, in meters. */
  double getShellWidth() const { return params_.shell_width_m; }

  /** \brief Returns how many planes the last segment() dropped in the shell test. */
  std::size_t getShellRejectedCount() const { return counts_.shell_rejected; }
  /** \brief Returns how many inliers the last segment()'s shell test took out of the
   * planes it kept or dropped. */
  std::size_t getShellRemovedCount() const { return counts_.shell_removed; }

  /** \brief Sets the sensor plane test. Stereo measures depth along the lines of
   * sight, and its error (eq. 4) grows with the square of the range, so the points of
   * any object are smeared along the lines of sight by up to about a meter at 15 m. A
   * plane that passes through (or near) the sensor contains the lines of sight of its
   * points and takes that smear for a surface: a vertical sheet through a tree trunk
   * or a pole, a horizontal sheet at the sensor's height through whatever stands
   * there. A plane whose distance from the input cloud's sensor_origin_, |n . o + d|,
   * is below `distance` is dropped, and its inliers are offered to no later plane
   * (they would only give the same plane again; they stay for the non-planar cells).
   * A road below a vehicle's camera (1.6 m), a facade beside the street or a wall in
   * front of the sensor lies farther. Not in the paper.
   * \param[in] distance_m in meters, in
   * sac_multi_plane_segmentation_ranges::MIN_SENSOR_DISTANCE (default 0: no test) */
  void setMinSensorDistance(double distance_m)
  {
    params_.min_sensor_distance_m = distance_m;
  }
  /** \brief Returns the smallest distance of a plane from the sensor origin, in
   * meters (0: no test). */
  double getMinSensorDistance() const { return params_.min_sensor_distance_m; }

  /** \brief Sets how far below the sensor a level plane must lie for the normal and
   * cluster tests to spare it as terrain. Terrain (a plane within 0.3 rad of the up
   * axis) is spared because a road's disparity is the sparsest and noisiest of a
   * street's surfaces and the terrain removal takes it whole; but a level plane just
   * below the sensor is no ground: spared, it takes a stripe of every wall and object
   * at its height (indoors, a plane at a table's height across a whole room; outdoors,
   * the car roofs). With a height h > 0, a level plane is spared only when the input
   * cloud's sensor_origin_ lies more than h above it (the sensor's least height above
   * the ground, as ground_removal's min_sensor_height_m). Not in the paper.
   * \param[in] height_m in meters, in
   * sac_multi_plane_segmentation_ranges::MIN_TERRAIN_SENSOR_HEIGHT (default 0.3, as
   * ground_removal's; 0: every level plane below the sensor is spared). A cloud whose
   * sensor_origin_ is not set (PCL's default, the origin) spares the level planes more
   * than this below the origin. */
  void setMinTerrainSensorHeight(double height_m)
  {
    params_.min_sensor_height_m = height_m;
  }
  /** \brief Returns the least height of the sensor above a level plane that the
   * normal and cluster tests spare as terrain, in meters. */
  double getMinTerrainSensorHeight() const { return params_.min_sensor_height_m; }

  /** \brief Sets the floor test of terrain: a level plane that the height rule of
   * setMinTerrainSensorHeight() would spare is spared only when the input's points
   * (those not given as inlier-only, before any plane took its inliers) lying more
   * than 0.3 m below it, within the 0.3 m squares (across the up axis) that its
   * selected points cover, number at most \a ratio per selected point. A road or a
   * floor has only its noise under it; a slab fitted through the bonnets of parked
   * cars, a table top or a plane through clutter in mid-air has the road, the floor or
   * the walls' lower parts. A plane not spared passes the normal and cluster tests
   * like a wall, and the ground removal, which takes the terrain planes and what
   * stands on them, does not see it as terrain. Not in the paper.
   * \param[in] ratio points per inlier, in
   * sac_multi_plane_segmentation_ranges::MAX_TERRAIN_BELOW_RATIO (default 0.05; 1: no
   * test, every level plane the height rule admits is spared). */
  void setMaxTerrainBelowRatio(double ratio)
  {
    params_.max_terrain_below_ratio = ratio;
  }
  /** \brief Returns the largest number of points below a level plane, per inlier,
   * for the normal and cluster tests to spare it as terrain. */
  double getMaxTerrainBelowRatio() const { return params_.max_terrain_below_ratio; }

  /** \brief Sets the cluster test. A plane's footprint (its inliers projected onto it,
   * in square cells of setClusterCell()) falls apart into connected clusters (cells up
   * to two apart along each axis are connected: a gap of one empty cell is bridged).
   * A surface is one large cluster, or a few; a plane fitted through separate objects
   * (two tree trunks, a pole and a facade behind it) or slicing a cluttered volume (car
   * bodies, a shop window, a canopy) holds many small ones. The inliers of every
   * cluster with fewer than `size` of them leave the plane (they stay for later planes
   * or the non-planar cells); a plane left with fewer than min_inliers is dropped.
   * Applied after the visibility and the shell tests. Not in the paper.
   * \param[in] size inliers, in sac_multi_plane_segmentation_ranges::MIN_CLUSTER_SIZE
   * (default 0: no test) */
  void setMinClusterSize(int size) { params_.min_cluster_size = size; }
  /** \brief Returns the fewest inliers of a footprint cluster (0: no test). */
  int getMinClusterSize() const { return params_.min_cluster_size; }

  /** \brief Sets the edge of the footprint cells of the cluster test; on a voxelised
   * cloud at least the voxel edge. \param[in] cell_m in meters, in
   * sac_multi_plane_segmentation_ranges::CLUSTER_CELL (default 0.2) */
  void setClusterCell(double cell_m) { params_.cluster_cell_m = cell_m; }
  /** \brief Returns the footprint cell edge of the cluster test, in meters. */
  double getClusterCell() const { return params_.cluster_cell_m; }

  /** \brief Returns how many planes the last segment() dropped in the cluster
   * test. */
  std::size_t getClusterRejectedCount() const { return counts_.cluster_rejected; }
  /** \brief Returns how many inliers the last segment()'s cluster test took out of
   * the planes it kept or dropped. */
  std::size_t getClusterRemovedCount() const { return counts_.cluster_removed; }

  /** \brief Returns how many planes the last segment() dropped in the sensor plane
   * test. */
  std::size_t getSensorPlaneRejectedCount() const
  {
    return counts_.sensor_plane_rejected;
  }
  /** \brief Returns how many inliers the last segment()'s sensor plane test took out
   * (the inliers of the planes it dropped). */
  std::size_t getSensorPlaneRemovedCount() const
  {
    return counts_.sensor_plane_removed;
  }

  /** \brief Returns how many planes the last segment() dropped in the visibility
   * test. */
  std::size_t getVisibilityRejectedCount() const { return counts_.visibility_rejected; }
  /** \brief Returns how many inliers the last segment()'s visibility test took out of
   * the planes it kept or dropped. */
  std::size_t getVisibilityRemovedCount() const { return counts_.visibility_removed; }

  /** \brief Sets the surface normals of the input cloud, one per input point (as
   * pcl::SACSegmentationFromNormals takes them; e.g. from
   * pcl::IntegralImageNormalEstimation on an organized cloud or pcl::NormalEstimation);
   * a NaN normal marks a point whose normal is unknown (judged by distance alone).
   * Without them (nullptr, the default) and with the normal test on, segment()
   * estimates them on a grid of setNormalCell() (detail::estimateGridNormals). A cloud
   * of another size than the input is an error of segment(). Replaces a function of
   * setNormalFunction(). \param[in] normals unit normals, any sign, or nullptr */
  void setInputNormals(const NormalCloudConstPtr& normals)
  {
    normals_ = normals;
    normal_function_ = nullptr;
  }
  /** \brief Returns the normals set by setInputNormals(), or nullptr. */
  NormalCloudConstPtr getInputNormals() const { return normals_; }

  /** \brief The surface normal of input point `index` (an index into the input
   * cloud), any sign, any length; NaN (or zero) where it is unknown. */
  using NormalFunction = std::function<Eigen::Vector3f(pcl::index_t index)>;
  /** \brief Sets a function that gives the normal test its normals on request, in
   * place of setInputNormals()' one per input point: segment() calls it at most once
   * per point, and only for the points the test examines (a hypothesis' eq. 11
   * inliers; never those of a terrain plane, which the test spares). For normals that
   * cost to compute (a fit in the disparity image, DisparityNormalEstimator) and a
   * cloud most of whose points are ground. The normals are those setInputNormals()
   * would give for the same values, and so is the segmentation. Replaces normals of
   * setInputNormals(); an empty function gives the estimate on a grid.
   * \param[in] normal_function called from segment()'s thread */
  void setNormalFunction(NormalFunction normal_function)
  {
    normal_function_ = std::move(normal_function);
    normals_.reset();
  }

  /** \brief Sets the normal test. Eq. 11 asks only how far a point lies from a plane:
   * a plane slicing a tree's canopy, a row of poles or a cluttered volume finds as many
   * points within d_T as a wall does. With the test, a point is an inlier of a plane
   * only when, in addition, its surface normal lies within `angle` of the plane's
   * normal (either side); a point without a normal (too few neighbours to tell) is
   * judged by its distance alone. The support of a real surface agrees, that of a
   * canopy scatters
   * (1 - cos(angle) of random directions agree: 13 % at 30 degrees). Terrain planes
   * (within 0.3 rad of the up axis, the sensor above them) are spared, as by the
   * cluster test. Not in the paper; PCL's SACSegmentationFromNormals weighs the same
   * angle into its distance. The test is on by default: without setInputNormals()
   * segment() estimates the normals on a grid of setNormalCell() (0.2 m, for street
   * scale stereo or LiDAR clouds), so any cloud works; for a cloud of another scale
   * set the cell (or give normals), and set 0 for the paper's distance-only eq. 11.
   * \param[in] angle_rad radians, in
   * sac_multi_plane_segmentation_ranges::MAX_NORMAL_ANGLE (default 0.5; 0: no
   * test) */
  void setMaxNormalAngle(double angle_rad) { params_.max_normal_angle_rad = angle_rad; }
  /** \brief Returns the largest angle of the normal test, in radians (0: no test). */
  double getMaxNormalAngle() const { return params_.max_normal_angle_rad; }

  /** \brief Sets the edge of the cubic cells of the normal estimation (without
   * setInputNormals()): each point's normal is fitted to the points of the 3 x 3 x 3
   * cells around its own, a cube of edge 3 `cell_m`. On a voxelised cloud about twice
   * the voxel edge (a stereo surface is as thick as its depth noise).
   * \param[in] cell_m meters, in sac_multi_plane_segmentation_ranges::NORMAL_CELL
   * (default 0.2) */
  void setNormalCell(double cell_m) { params_.normal_cell_m = cell_m; }
  /** \brief Returns the cell edge of the normal estimation, in meters. */
  double getNormalCell() const { return params_.normal_cell_m; }

  /** \brief Sets the support test of the normal test: a hypothesis whose eq. 11
   * inliers by distance alone that have a normal agree with its normal less often
   * than `ratio` is rejected whatever its count: its support scatters in normal (a
   * plane through vegetation or clutter, or across a surface at an angle). Its
   * support that disagrees leaves the search (it would give the same plane again);
   * the points that agree or have no normal stay. Needs
   * setMaxNormalAngle() > 0. \param[in] ratio in
   * sac_multi_plane_segmentation_ranges::MIN_NORMAL_AGREEMENT (default 0.35; 0: no
   * test) */
  void setMinNormalAgreement(double ratio) { params_.min_normal_agreement = ratio; }
  /** \brief Returns the smallest share of agreeing support of a hypothesis. */
  double getMinNormalAgreement() const { return params_.min_normal_agreement; }

  /** \brief Returns how many hypotheses the last segment() dropped because their
   * support scattered in normal (setMinNormalAgreement()). */
  std::size_t getNormalRejectedCount() const { return counts_.normal_rejected; }
  /** \brief Returns how many eq. 11 inliers (by distance) the last segment()'s
   * normal test took out of the hypotheses that passed its support test. */
  std::size_t getNormalRemovedCount() const { return counts_.normal_removed; }

  /** \brief Sets the up axis of eqs. 2-3 (the paper's z axis); it is normalised.
   * \param[in] axis non-zero (default (0, 0, 1); (0, -1, 0) for a camera frame) */
  void setUpAxis(const Eigen::Vector3f& axis) { up_axis_ = axis; }
  /** \brief Returns the up axis as set. */
  Eigen::Vector3f getUpAxis() const { return up_axis_; }

  /** \brief Sets the seed of the subsample and of the per-round sample shuffles.
   * \param[in] seed any value (default 0) */
  void setSeed(unsigned seed) { params_.seed = seed; }
  /** \brief Returns the seed. */
  unsigned getSeed() const { return params_.seed; }

  /** \brief Sets the size of the input subsample used when no sample cloud is set.
   * \param[in] max_sample_size in sac_multi_plane_segmentation_ranges::MAX_SAMPLE_SIZE
   * (default 20000 points) */
  void setMaxSampleSize(int max_sample_size)
  {
    params_.max_sample_size = max_sample_size;
  }
  /** \brief Returns the size of the input subsample, in points. */
  int getMaxSampleSize() const { return params_.max_sample_size; }

  /** \brief Segments the input cloud (within the indices) into planes.
   * \param[out] planes the planes, sorted by descending dense inlier count; empty on
   * degenerate input or invalid parameters. Headers are the input's. */
  void segment(PlanarSegments& planes);

  /** \brief Segments the input cloud into planes, as pcl::SACSegmentation does.
   * \param[out] model_coefficients [a, b, c, d] per plane (unit normal, d in meters)
   * \param[out] inliers dense inliers (eq. 11) per plane, parallel to
   * model_coefficients, sorted by descending size */
  void segment(std::vector<pcl::ModelCoefficients>& model_coefficients,
               std::vector<pcl::PointIndices>& inliers);

  /** \brief Checks the parameters against their documented ranges, as segment() does
   * before it starts (it then reports the same text with PCL_ERROR and gives no
   * planes).
   * \return nullptr when every parameter is valid, else what is wrong (e.g.
   * "distance_threshold must be in (0, 1] m") */
  const char* checkParameters() const;

protected:
  using pcl::PCLBase<PointT>::input_;
  using pcl::PCLBase<PointT>::indices_;

  /** \brief Base initCompute plus checkParameters(); PCL_ERROR if false. */
  bool initCompute();

  /** \brief The algorithm; called between initCompute() and deinitCompute(). */
  virtual void applySegmentation(PlanarSegments& planes);

  /** \brief Returns the class name for messages. */
  const std::string& getClassName() const { return class_name_; }

  /** \brief Class name used in messages. */
  std::string class_name_{"SACMultiPlaneSegmentation"};
  /** \brief Cloud the hypotheses are drawn from, or nullptr. */
  PointCloudConstPtr sample_cloud_;
  /** \brief Points that may join planes but make none (setInlierOnlyIndices()). */
  pcl::IndicesConstPtr inlier_only_indices_;
  /** \brief The parameters the pipeline sets. */
  Params params_;
  /** \brief Delta d / (B f) of the range-dependent eq. 11 threshold, in 1/m. */
  double depth_noise_coefficient_{0.0};
  /** \brief Up axis of eqs. 2-3. */
  Eigen::Vector3f up_axis_{0.0f, 0.0f, 1.0f};
  /** \brief What the last segment()'s plane tests took out. */
  PlaneTestCounts counts_;
  /** \brief Surface normals of the input points, or nullptr. */
  NormalCloudConstPtr normals_;
  /** \brief Surface normals of input points on request, or empty. */
  NormalFunction normal_function_;

private:
  /** \brief Buffers that the rounds of applySegmentation() reuse. */
  struct RoundBuffers {
    /** \brief Positions in the dense store of the points in the refinement slab. */
    std::vector<std::size_t> slab_points;
    /** \brief A subsample of dense points (struct of arrays), in meters. */
    std::vector<float> local_x, local_y, local_z;
  };

  /** \brief Fills \a dense with the finite input points within the indices (the
   * inlier-only ones last) and, where eq. 11 varies per point, their thresholds.
   * \param[in] origin the sensor origin, in meters
   * \param[in] d_t the fixed eq. 11 threshold, in meters */
  void collectDensePoints(const Eigen::Vector3f& origin,
                          float d_t,
                          detail::DensePoints& dense) const;

  /** \brief Draws the sample the hypotheses come from: the finite points of the sample
   * cloud, or a seeded subsample (sorted) of the primary dense points. */
  void drawSample(const detail::DensePoints& dense,
                  std::mt19937& rng,
                  pcl::Indices& sample) const;

  /** \brief Shuffles the remaining sample and fits a plane to it by sample consensus
   * at \a sample_t (meters), oriented toward \a origin.
   * \return false when no plane with min_sample_inliers was found */
  bool estimateSamplePlane(const PointCloudConstPtr& sample_cloud,
                           pcl::Indices& remaining,
                           float sample_t,
                           const Eigen::Vector3f& origin,
                           std::mt19937& rng,
                           pcl::Indices& sac_inliers,
                           Eigen::Vector4f& plane) const;

  /** \brief Re-estimates \a plane by RANSAC on a subsample of the dense points in a
   * wide slab around it (thresholds in meters). */
  void refineOnDenseSlab(detail::DensePoints& dense,
                         float sample_t,
                         float d_t,
                         const Eigen::Vector3f& origin,
                         std::mt19937& rng,
                         RoundBuffers& buffers,
                         Eigen::Vector4f& plane) const;

  /** \brief Replaces \a plane by a RANSAC plane of a dense subsample when that one has
   * more eq. 11 inliers. \return true when it was replaced */
  bool tryDenseHypothesis(detail::DensePoints& dense,
                          float d_t,
                          const Eigen::Vector3f& origin,
                          std::mt19937& rng,
                          RoundBuffers& buffers,
                          Eigen::Vector4f& plane) const;

  /** \brief Optimises \a plane (LO-RANSAC, PCA refit) and selects its eq. 11 inliers
   * in \a dense (its mask). \return the number of inliers */
  std::size_t selectDenseInliers(detail::DensePoints& dense,
                                 float d_t,
                                 const Eigen::Vector3f& origin,
                                 std::mt19937& rng,
                                 Eigen::Vector4f& plane,
                                 pcl::Indices& inliers) const;

  /** \brief Removes from \a remaining the taken sample points and those within
   * \a sample_t (meters) of \a plane. */
  void removeSampleOnPlane(const PointCloud& sample_cloud,
                           const Eigen::Vector4f& plane,
                           float sample_t,
                           const std::vector<std::uint8_t>& sample_taken,
                           pcl::Indices& remaining) const;

  /** \brief The inliers that count toward min_inliers: \a count, or the selected
   * primary points alone when the inlier-only points do not count. */
  std::size_t supportCount(const detail::DensePoints& dense, std::size_t count) const;

  /** \brief The support test of the normal test: whether at least
   * min_normal_agreement of the plane's eq. 11 inliers by distance that have a normal
   * agree with it. When they do, leaves the mask on the plane's inliers (with the
   * normal test); when not, takes the support that disagrees out of \a dense (it
   * would give the same plane again). */
  bool passesNormalAgreement(detail::DensePoints& dense,
                             const Eigen::Vector4f& plane,
                             float d_t);

  /** \brief Applies min_inliers and the sensor, visibility, shell and cluster tests to
   * a plane whose inliers are selected in \a dense, taking out the inliers they reject
   * and counting the rejections. \return false when the plane is dropped */
  bool passesPlaneTests(detail::DensePoints& dense,
                        const detail::DensePoints& all,
                        const Eigen::Vector4f& plane,
                        const Eigen::Vector3f& origin,
                        float d_t,
                        std::size_t& count);

  /** \brief Merges planes whose normals and offsets are within the merge thresholds,
   * refitting the merged plane. */
  void mergeDuplicatePlanes(PlanarSegments& planes,
                            const Eigen::Vector3f& origin) const;

  /** \brief Sorts each plane's inliers, sets its centroid, eqs. 2-3 tilts and headers,
   * and sorts the planes by descending inlier count. */
  void describePlanes(PlanarSegments& planes, const Eigen::Vector3f& up) const;

public:
  PCL_MAKE_ALIGNED_OPERATOR_NEW
};

} // namespace planar_grid

#ifdef PCL_NO_PRECOMPILE
#include <planar_grid/segmentation/impl/sac_multi_plane_segmentation.hpp>
#endif
