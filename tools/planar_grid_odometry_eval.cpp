// SPDX-License-Identifier: BSD-3-Clause
// planar_grid_odometry_eval: stereo visual odometry (paper eq. 8) on real data, against
// the Karlsruhe INS positions or the EuRoC V1_01 ground-truth poses.
#include <planar_grid/core/atomic_file.h>
#include <planar_grid/core/exceptions.h>
#include <planar_grid/odometry/stereo_odometry.h>
#include <planar_grid/odometry/trajectory_io.h>
#include <planar_grid/odometry/trajectory_metrics.h>
#include <planar_grid/stereo/calibration_io.h>
#include <planar_grid/stereo/stereo_feature_matcher.h>

#include <pcl/console/parse.h>
#include <pcl/console/print.h>
#include <pcl/console/time.h>

#include <nlohmann/json.hpp>
#include <opencv2/imgcodecs.hpp>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <exception>
#include <string>
#include <utility>
#include <vector>

#include "cli.h"

namespace {

using planar_grid::StereoFeatureMatcher;
using planar_grid::StereoFeatures;
using planar_grid::StereoOdometry;

void
printHelp(const char* program)
{
  pcl::console::print_info(
    "Stereo visual odometry (paper eq. 8) evaluated on real data.\n"
    "Usage: %s --sequence karlsruhe|kitti|euroc [options]\n"
    "  --sequence NAME    karlsruhe (112 frames, INS positions), kitti (the 51-frame\n"
    "                     snippet, ground-truth poses) or euroc (pairs 2 -> 3)\n"
    "  --data DIR         data folder (default ../shared/data)\n"
    "  --features NAME    sift, orb or orb_grid (default sift)\n"
    "  --max_features N   most key points per image (default 2000)\n"
    "  --max_range_m X    features farther than this are dropped, metres (default 40)\n"
    "  --threshold_m X    RANSAC distance threshold, metres (default 0.1)\n"
    "  --reference_depth_m X  depth beyond which the threshold grows with z^2 and\n"
    "                     the refinement is weighted, metres; 0 = off (default 0)\n"
    "  --no_reprojection  skip the stereo reprojection refinement (3D RANSAC + SVD "
    "only;\n"
    "                     the epipolar refinement needs it and is skipped too)\n"
    "  --no_epipolar      skip the epipolar rotation refinement (default: on)\n"
    "  --no_disparity_offset  do not estimate the disparity offset with the motion\n"
    "                     (default: estimated, see StereoOdometry::Params)\n"
    "  --disparity_offset_px X  the offset's prior (or, with --no_disparity_offset,\n"
    "                     fixed) value: true disparity = measured + X, px (default 0)\n"
    "  --disparity_offset_sigma_px X  the prior's standard deviation, px (default 1)\n"
    "  --disparity_offset_memory X  share of the offset's information carried to the\n"
    "                     next frame pair, [0, 1] (default 0.8; 1: one offset per "
    "run)\n"
    "  --step_analysis    karlsruhe: per section of the drive, the INS, estimated and\n"
    "                     near-only (disparity >= 40 px, z <= 9.2 m) / far-only (< 20\n"
    "                     px, z > 18 m) step lengths (default: off)\n"
    "  --ins_lever_arm_m F,L  karlsruhe: also evaluate against the INS positions "
    "moved\n"
    "                     F m forward and L m left along the track (the INS is not at\n"
    "                     the camera); the headline figures stay against insdata.txt\n"
    "                     (default: none)\n"
    "  --output FILE      write the figures as JSON (default: none)\n"
    "  -h                 this help\n"
    "  --version          print the name and version\n",
    program);
}

/** \brief Reads a grey image; throws when it is missing. */
cv::Mat
readImage(const std::string& path)
{
  cv::Mat image = cv::imread(path, cv::IMREAD_GRAYSCALE);
  if (image.empty())
    throw planar_grid::IOError("cannot read image " + path);
  return image;
}

/** \brief printf into a std::string. */
std::string
formatPath(const std::string& pattern, int index)
{
  std::vector<char> buffer(pattern.size() + 32);
  std::snprintf(buffer.data(), buffer.size(), pattern.c_str(), index);
  return buffer.data();
}

double
median(std::vector<double> values)
{
  if (values.empty())
    return 0.0;
  std::sort(values.begin(), values.end());
  return values[values.size() / 2];
}

double
mean(const std::vector<double>& values)
{
  if (values.empty())
    return 0.0;
  double sum = 0.0;
  for (const double value : values)
    sum += value;
  return sum / static_cast<double>(values.size());
}

nlohmann::json
timingJson(const std::vector<double>& values)
{
  return {
    {"mean_ms", mean(values)},
    {"median_ms", median(values)},
    {"max_ms", values.empty() ? 0.0 : *std::max_element(values.begin(), values.end())}};
}

/** \brief Heading change (degrees, about the vertical) between the first and the last
 * \a window steps of a track: for the estimate, the camera's horizontal direction of
 * travel (x, z of the first camera frame); for the INS, its (x, y) steps. */
double
headingChangeDeg(const planar_grid::Trajectory& trajectory,
                 bool camera_frame,
                 int window)
{
  const auto direction = [&](std::size_t from, std::size_t to) {
    const Eigen::Vector3d step =
      trajectory[to].translation() - trajectory[from].translation();
    return camera_frame ? std::atan2(step.x(), step.z())
                        : -std::atan2(step.y(), step.x());
  };
  const std::size_t n = trajectory.size();
  const auto w = static_cast<std::size_t>(window);
  double change = direction(n - 1 - w, n - 1) - direction(0, w);
  while (change > M_PI)
    change -= 2.0 * M_PI;
  while (change < -M_PI)
    change += 2.0 * M_PI;
  return change * 180.0 / M_PI;
}

/** \brief RTE (all segments, percent) and ATE (metres) of a trajectory. */
std::pair<double, double>
rteAndAte(const planar_grid::Trajectory& estimated,
          const planar_grid::Trajectory& reference)
{
  const auto rte = planar_grid::relativeTranslationError(
    estimated, reference, {10.0, 20.0, 30.0, 40.0, 50.0});
  return {planar_grid::meanRelativeTranslationError(rte),
          planar_grid::absoluteTrajectoryError(estimated, reference)};
}

/** \brief The features whose disparity lies in [min_px, max_px). */
StereoFeatures
disparityBand(const StereoFeatures& features, double min_px, double max_px)
{
  StereoFeatures band;
  std::vector<int> rows;
  for (std::size_t i = 0; i < features.size(); ++i) {
    if (features.disparities[i] < min_px || features.disparities[i] >= max_px)
      continue;
    rows.push_back(static_cast<int>(i));
    band.points.push_back(features.points[i]);
    band.keypoints_left.push_back(features.keypoints_left[i]);
    band.keypoints_right.push_back(features.keypoints_right[i]);
    band.disparities.push_back(features.disparities[i]);
  }
  band.descriptors.create(static_cast<int>(rows.size()), features.descriptors.cols,
                          features.descriptors.type());
  for (std::size_t k = 0; k < rows.size(); ++k)
    features.descriptors.row(rows[k]).copyTo(band.descriptors.row(static_cast<int>(k)));
  return band;
}

/** \brief Step lengths of one section of the drive (sums over its frame pairs). */
struct SectionSteps {
  std::size_t first_frame, last_frame;
  const char* what;
  std::size_t pairs{0};
  double ins{0.0}, estimated{0.0}, near{0.0}, far{0.0};
};

/** \brief The errors of the odometry's trajectory against a reference with one pose
 * per frame: frames, flagged frames, both path lengths (m), ATE RMSE (m), the mean RTE
 * (%) and the RTE by segment length (10-50 m), as JSON; printed under \a title. */
nlohmann::json
trajectoryErrors(const std::string& sequence,
                 const planar_grid::VisualOdometry& odometry,
                 const planar_grid::Trajectory& reference,
                 const char* title)
{
  const planar_grid::Trajectory& estimated = odometry.getTrajectory();
  const auto rte = planar_grid::relativeTranslationError(
    estimated, reference, {10.0, 20.0, 30.0, 40.0, 50.0});
  const double ate = planar_grid::absoluteTrajectoryError(estimated, reference);
  double path_reference = 0.0, path_estimated = 0.0;
  for (std::size_t i = 1; i < estimated.size(); ++i) {
    path_reference +=
      (reference[i].translation() - reference[i - 1].translation()).norm();
    path_estimated +=
      (estimated[i].translation() - estimated[i - 1].translation()).norm();
  }
  nlohmann::json json;
  json["sequence"] = sequence;
  json["frames"] = estimated.size();
  json["flagged_frames"] = odometry.getFlaggedFrames();
  json["path_length_gt_m"] = path_reference;
  json["path_length_estimated_m"] = path_estimated;
  json["ate_rmse_m"] = ate;
  json["rte_percent"] = planar_grid::meanRelativeTranslationError(rte);
  for (const auto& error : rte)
    json["rte_by_length"].push_back({{"segment_length_m", error.segment_length_m},
                                     {"segments", error.segments},
                                     {"mean_error_percent", error.mean_error_percent}});
  pcl::console::print_info("%s: %zu frames, GT path %.2f m, estimated %.2f m\n", title,
                           estimated.size(), path_reference, path_estimated);
  for (const auto& error : rte)
    pcl::console::print_info("  RTE %4.0f m: %6.3f %% over %zu segments\n",
                             error.segment_length_m, error.mean_error_percent,
                             error.segments);
  pcl::console::print_info("  RTE (all segments): %.3f %%, ATE RMSE: %.3f m\n",
                           json["rte_percent"].get<double>(), ate);
  // The disparity offset the odometry ended with; its standard deviation is for
  // reprojection residuals of 1 px (the real ones are smaller, so it is an upper
  // bound).
  json["disparity_offset_px"] = odometry.getDisparityOffset();
  const double information = odometry.getDisparityOffsetInformation();
  json["disparity_offset_sd_px"] =
    information > 0.0 ? 1.0 / std::sqrt(information) : 0.0;
  pcl::console::print_info("  disparity offset: %+.3f px (sd %.3f px)\n",
                           odometry.getDisparityOffset(),
                           json["disparity_offset_sd_px"].get<double>());
  for (std::size_t i = 1; i < estimated.size(); ++i) {
    const planar_grid::OdometryResult& result = odometry.getResults()[i];
    json["per_frame_motion"].push_back(
      {{"frame", i},
       {"valid", result.valid},
       {"inliers", result.inliers},
       {"step_estimated_m",
        (estimated[i].translation() - estimated[i - 1].translation()).norm()},
       {"step_reference_m",
        (reference[i].translation() - reference[i - 1].translation()).norm()},
       {"disparity_offset_px", result.disparity_offset_px}});
  }
  return json;
}

/** \brief Matches the stereo pair (\a left_path, \a right_path) into \a current and
 * adds it to \a odometry as frame \a frame, timing both (\a match_ms, \a odometry_ms)
 * and printing the frame's line. */
const planar_grid::OdometryResult&
trackFrame(const StereoFeatureMatcher& matcher,
           const planar_grid::StereoCameraModel& model,
           const std::string& left_path,
           const std::string& right_path,
           std::size_t frame,
           planar_grid::VisualOdometry& odometry,
           StereoFeatures& current,
           double& match_ms,
           double& odometry_ms)
{
  const cv::Mat left = readImage(left_path);
  const cv::Mat right = readImage(right_path);
  pcl::console::TicToc timer;
  timer.tic();
  matcher.match(left, right, model.calibration, current);
  match_ms = timer.toc();
  timer.tic();
  const planar_grid::OdometryResult& result = odometry.addFrame(current);
  odometry_ms = timer.toc();
  pcl::console::print_info(
    "frame %3zu: %4zu features [%6.1f ms], %4zu matches, %4zu inliers [%5.1f ms]%s\n",
    frame, current.size(), match_ms, result.correspondences, result.inliers,
    odometry_ms, result.valid ? "" : " FLAGGED");
  return result;
}

/** \brief --step_analysis: the same estimator on near-only and far-only features of
 * the frame pair (\a previous, \a current) of frame \a frame; the pair counts in its
 * section when the chained, near and far estimates are all valid. */
void
addStepAnalysis(std::vector<SectionSteps>& sections,
                std::size_t frame,
                const planar_grid::OdometryResult& result,
                const StereoFeatures& previous,
                const StereoFeatures& current,
                const StereoOdometry& band_odometry,
                const planar_grid::Trajectory& ground_truth)
{
  const planar_grid::OdometryResult near = band_odometry.estimate(
    disparityBand(previous, 40.0, 1e9), disparityBand(current, 40.0, 1e9));
  const planar_grid::OdometryResult far = band_odometry.estimate(
    disparityBand(previous, 0.0, 20.0), disparityBand(current, 0.0, 20.0));
  for (SectionSteps& section : sections)
    if (near.valid && far.valid && frame >= section.first_frame
        && frame <= section.last_frame) {
      ++section.pairs;
      section.ins +=
        (ground_truth[frame].translation() - ground_truth[frame - 1].translation())
          .norm();
      section.estimated += result.previous_T_current.translation().norm();
      section.near += near.previous_T_current.translation().norm();
      section.far += far.previous_T_current.translation().norm();
    }
}

/** \brief Karlsruhe's diagnostics in \a json: the heading change over the sequence
 * (the INS's from its track, over the first and last 5 steps; straight at both ends),
 * the errors left when the estimated step directions are re-chained with the INS step
 * lengths (direction errors only), the epipolar-refined frames, and the errors
 * against the INS moved by \a lever_arm_m. Returns the direction-only (RTE, ATE). */
std::pair<double, double>
addKarlsruheDiagnostics(nlohmann::json& json,
                        const planar_grid::VisualOdometry& odometry,
                        const planar_grid::Trajectory& ground_truth,
                        const std::vector<double>& lever_arm_m)
{
  const planar_grid::Trajectory& estimated = odometry.getTrajectory();
  json["heading_change_estimated_deg"] = headingChangeDeg(estimated, true, 5);
  json["heading_change_ins_track_deg"] = headingChangeDeg(ground_truth, false, 5);
  const auto direction_only = rteAndAte(
    planar_grid::withReferenceStepLengths(estimated, ground_truth), ground_truth);
  json["rte_with_ins_step_lengths_percent"] = direction_only.first;
  json["ate_with_ins_step_lengths_m"] = direction_only.second;
  std::size_t epipolar = 0;
  for (const auto& result : odometry.getResults())
    epipolar += result.epipolar_refined ? 1 : 0;
  json["epipolar_refined_frames"] = epipolar;
  if (lever_arm_m.size() == 2) {
    const planar_grid::Trajectory moved =
      planar_grid::offsetAlongTrack(ground_truth, lever_arm_m[0], lever_arm_m[1]);
    const auto with_arm = rteAndAte(estimated, moved);
    const auto with_arm_direction =
      rteAndAte(planar_grid::withReferenceStepLengths(estimated, moved), moved);
    json["ins_lever_arm_m"] = lever_arm_m;
    json["lever_arm_rte_percent"] = with_arm.first;
    json["lever_arm_ate_m"] = with_arm.second;
    json["lever_arm_rte_with_ins_step_lengths_percent"] = with_arm_direction.first;
    json["lever_arm_ate_with_ins_step_lengths_m"] = with_arm_direction.second;
  }
  return direction_only;
}

/** \brief Per frame: the estimate's figures and step lengths against the INS, and
 * the estimated and INS positions. */
void
addPerFrame(nlohmann::json& json,
            const planar_grid::VisualOdometry& odometry,
            const planar_grid::Trajectory& ground_truth,
            const std::vector<double>& odometry_ms)
{
  const planar_grid::Trajectory& estimated = odometry.getTrajectory();
  for (std::size_t i = 1; i < estimated.size(); ++i) {
    const planar_grid::OdometryResult& result = odometry.getResults()[i];
    json["per_frame"].push_back(
      {{"frame", i},
       {"valid", result.valid},
       {"correspondences", result.correspondences},
       {"inliers", result.inliers},
       {"epipolar_refined", result.epipolar_refined},
       {"step_estimated_m",
        (estimated[i].translation() - estimated[i - 1].translation()).norm()},
       {"step_gt_m",
        (ground_truth[i].translation() - ground_truth[i - 1].translation()).norm()},
       {"odometry_ms", odometry_ms[i - 1]}});
  }
  for (std::size_t i = 0; i < estimated.size(); ++i) {
    const Eigen::Vector3d p = estimated[i].translation();
    const Eigen::Vector3d g = ground_truth[i].translation();
    json["positions_estimated_m"].push_back({p.x(), p.y(), p.z()});
    json["positions_gt_m"].push_back({g.x(), g.y(), g.z()});
  }
}

/** \brief Prints Karlsruhe's summary: the flagged and epipolar-refined frames, the
 * heading change and direction-only errors, the step analysis per section (also in
 * \a json) and the lever arm's errors. */
void
printKarlsruheSummary(nlohmann::json& json,
                      const planar_grid::VisualOdometry& odometry,
                      const std::pair<double, double>& direction_only,
                      const std::vector<SectionSteps>& sections,
                      bool step_analysis,
                      const std::vector<double>& lever_arm_m)
{
  const std::size_t epipolar = json["epipolar_refined_frames"].get<std::size_t>();
  std::string flagged;
  for (const std::size_t frame : odometry.getFlaggedFrames())
    flagged += " " + std::to_string(frame);
  pcl::console::print_info("  flagged frames: %zu%s; epipolar-refined frames: %zu\n",
                           odometry.getFlaggedFrames().size(), flagged.c_str(),
                           epipolar);
  pcl::console::print_info(
    "  heading change: estimated %.2f deg, INS track %.2f deg; with the INS step "
    "lengths (direction errors only): RTE %.3f %%, ATE %.3f m\n",
    json["heading_change_estimated_deg"].get<double>(),
    json["heading_change_ins_track_deg"].get<double>(), direction_only.first,
    direction_only.second);
  for (const SectionSteps& section : sections) {
    if (!step_analysis)
      break;
    json["step_analysis"].push_back({{"first_frame", section.first_frame},
                                     {"last_frame", section.last_frame},
                                     {"section", section.what},
                                     {"pairs", section.pairs},
                                     {"ins_m", section.ins},
                                     {"estimated_m", section.estimated},
                                     {"near_only_m", section.near},
                                     {"far_only_m", section.far}});
    const double ins = section.ins > 0.0 ? section.ins : 1.0;
    pcl::console::print_info(
      "  frames %3zu-%3zu (%s): %zu pairs, INS %.2f m; estimated x%.3f, near-only "
      "x%.3f, far-only x%.3f of the INS\n",
      section.first_frame, section.last_frame, section.what, section.pairs, section.ins,
      section.estimated / ins, section.near / ins, section.far / ins);
  }
  if (lever_arm_m.size() == 2)
    pcl::console::print_info(
      "  against the INS moved %.2f m forward, %.2f m left: RTE %.3f %%, ATE %.3f m; "
      "with its step lengths: RTE %.3f %%, ATE %.3f m\n",
      lever_arm_m[0], lever_arm_m[1], json["lever_arm_rte_percent"].get<double>(),
      json["lever_arm_ate_m"].get<double>(),
      json["lever_arm_rte_with_ins_step_lengths_percent"].get<double>(),
      json["lever_arm_ate_with_ins_step_lengths_m"].get<double>());
}

nlohmann::json
runKarlsruhe(const std::string& data_dir,
             const StereoFeatureMatcher& matcher,
             const StereoOdometry::Params& odometry_params,
             bool reprojection,
             const std::vector<double>& lever_arm_m,
             bool step_analysis)
{
  const std::string dir = data_dir + "/karlsruhe_2010_03_09_drive_0023";
  const planar_grid::StereoCameraModel model = planar_grid::loadStereoCalibration(
    planar_grid::CalibrationFormat::KARLSRUHE, dir + "/calib.txt");
  const planar_grid::Trajectory ground_truth =
    planar_grid::loadKarlsruheInsData(dir + "/insdata.txt");
  pcl::console::print_info("Loaded %zu INS poses from %s/insdata.txt\n",
                           ground_truth.size(), dir.c_str());

  planar_grid::VisualOdometry odometry(
    odometry_params, planar_grid::ConstantVelocityMotionModel::Params());
  if (reprojection)
    odometry.setCalibration(model.calibration);
  std::vector<double> feature_ms, odometry_ms, features, inliers;
  // --step_analysis: the same estimator on near-only and far-only features; a pair
  // counts in its section when the chained, near and far estimates are all valid.
  StereoOdometry band_odometry(odometry_params);
  if (reprojection)
    band_odometry.setCalibration(model.calibration);
  std::vector<SectionSteps> sections{{1, 35, "fast straight, 12 m/s"},
                                     {36, 60, "braking, 8-11 m/s"},
                                     {61, 100, "90 deg right turn, 5 m/s"},
                                     {101, 111, "after the turn, 6 m/s"}};
  StereoFeatures previous;
  for (std::size_t frame = 0; frame < ground_truth.size(); ++frame) {
    const int index = static_cast<int>(frame);
    StereoFeatures current;
    double match_ms = 0.0, elapsed = 0.0;
    const planar_grid::OdometryResult& result =
      trackFrame(matcher, model, formatPath(dir + "/left/I1_%06d.png", index),
                 formatPath(dir + "/right/I2_%06d.png", index), frame, odometry,
                 current, match_ms, elapsed);
    feature_ms.push_back(match_ms);
    features.push_back(static_cast<double>(current.size()));
    if (frame > 0) {
      odometry_ms.push_back(elapsed);
      inliers.push_back(static_cast<double>(result.inliers));
    }
    if (step_analysis && frame > 0 && result.valid)
      addStepAnalysis(sections, frame, result, previous, current, band_odometry,
                      ground_truth);
    previous = std::move(current);
  }

  nlohmann::json json = trajectoryErrors("karlsruhe_2010_03_09_drive_0023", odometry,
                                         ground_truth, "Karlsruhe");
  const std::pair<double, double> direction_only =
    addKarlsruheDiagnostics(json, odometry, ground_truth, lever_arm_m);
  addPerFrame(json, odometry, ground_truth, odometry_ms);
  json["features_per_frame_mean"] = mean(features);
  json["inliers_per_frame_mean"] = mean(inliers);
  json["feature_extraction_and_stereo_matching"] = timingJson(feature_ms);
  json["odometry"] = timingJson(odometry_ms);

  pcl::console::print_info("  features+stereo: mean %.1f ms; odometry: mean %.1f ms, "
                           "median %.1f ms, max %.1f ms\n",
                           mean(feature_ms), mean(odometry_ms), median(odometry_ms),
                           json["odometry"]["max_ms"].get<double>());
  printKarlsruheSummary(json, odometry, direction_only, sections, step_analysis,
                        lever_arm_m);
  return json;
}

/** \brief The KITTI odometry snippet (51 frames): RTE / ATE against its ground-truth
 * poses, computed as for Karlsruhe. */
nlohmann::json
runKitti(const std::string& data_dir,
         const StereoFeatureMatcher& matcher,
         const StereoOdometry::Params& odometry_params,
         bool reprojection)
{
  const std::string dir = data_dir + "/kitti_odometry_snippet_2";
  const planar_grid::StereoCameraModel model = planar_grid::loadStereoCalibration(
    planar_grid::CalibrationFormat::KITTI, dir + "/calib.txt");
  // The odometry's trajectory starts at the identity in the first camera's optical
  // frame, KITTI's own world; the reader gives the z-up world, so go back.
  planar_grid::Trajectory ground_truth =
    planar_grid::loadKittiPoses(dir + "/poses.txt");
  const Eigen::Isometry3d optical_T_z_up =
    planar_grid::zUpWorldFrom(planar_grid::WorldConvention::OPTICAL).inverse();
  for (auto& pose : ground_truth)
    pose = optical_T_z_up * pose;
  planar_grid::VisualOdometry odometry(
    odometry_params, planar_grid::ConstantVelocityMotionModel::Params());
  if (reprojection)
    odometry.setCalibration(model.calibration);
  std::vector<double> feature_ms, odometry_ms, features;
  for (std::size_t frame = 0; frame < ground_truth.size(); ++frame) {
    const int index = static_cast<int>(frame);
    StereoFeatures current;
    double match_ms = 0.0, elapsed = 0.0;
    trackFrame(matcher, model, formatPath(dir + "/image_l/%06d.png", index),
               formatPath(dir + "/image_r/%06d.png", index), frame, odometry, current,
               match_ms, elapsed);
    feature_ms.push_back(match_ms);
    odometry_ms.push_back(elapsed);
    features.push_back(static_cast<double>(current.size()));
  }
  const planar_grid::Trajectory& estimated = odometry.getTrajectory();
  nlohmann::json json =
    trajectoryErrors("kitti_odometry_snippet_2", odometry, ground_truth, "KITTI");
  json["heading_change_estimated_deg"] = headingChangeDeg(estimated, true, 5);
  json["heading_change_gt_deg"] = headingChangeDeg(ground_truth, true, 5);
  json["features_per_frame_mean"] = mean(features);
  json["feature_extraction_and_stereo_matching"] = timingJson(feature_ms);
  json["odometry"] = timingJson(odometry_ms);
  pcl::console::print_info(
    "  heading change: estimated %.2f deg, ground truth %.2f deg; flagged frames: "
    "%zu\n",
    json["heading_change_estimated_deg"].get<double>(),
    json["heading_change_gt_deg"].get<double>(), odometry.getFlaggedFrames().size());
  pcl::console::print_info("  features+stereo: mean %.1f ms; odometry: mean %.1f ms\n",
                           mean(feature_ms), mean(odometry_ms));
  return json;
}

nlohmann::json
runEuroc(const std::string& data_dir,
         const StereoFeatureMatcher& matcher,
         const StereoOdometry::Params& odometry_params,
         bool reprojection)
{
  const std::string dir = data_dir + "/euroc_v1_01_pairs";
  const planar_grid::StereoCameraModel model = planar_grid::loadStereoCalibration(
    planar_grid::CalibrationFormat::EUROC, dir + "/sensorLeft.yaml",
    dir + "/sensorRight.yaml");
  const planar_grid::IndexedPoses body_poses =
    planar_grid::loadEurocBodyPoses(dir + "/gt_body_poses.txt");
  const int pairs[2] = {2, 3};
  StereoFeatures features[2];
  std::vector<double> feature_ms;
  pcl::console::TicToc timer;
  for (int k = 0; k < 2; ++k) {
    cv::Mat left, right;
    model.rectifier.rectify(
      readImage(dir + "/left_img_" + std::to_string(pairs[k]) + ".png"),
      readImage(dir + "/right_img_" + std::to_string(pairs[k]) + ".png"), left, right);
    timer.tic();
    matcher.match(left, right, model.calibration, features[k]);
    feature_ms.push_back(timer.toc());
  }
  StereoOdometry odometry(odometry_params);
  if (reprojection)
    odometry.setCalibration(model.calibration);
  timer.tic();
  const planar_grid::OdometryResult result =
    odometry.estimate(features[0], features[1]);
  const double odometry_ms = timer.toc();

  for (const int pair : pairs)
    if (body_poses.count(pair) == 0)
      throw planar_grid::IOError(dir + "/gt_body_poses.txt: no pose for pair "
                                 + std::to_string(pair));
  const Eigen::Isometry3d world_T_camera2 = body_poses.at(2) * model.body_T_left;
  const Eigen::Isometry3d world_T_camera3 = body_poses.at(3) * model.body_T_left;
  // The features live in the rectified left camera frame, rotated by R1 against cam0:
  // the true motion in that frame is R1 * (cam0_2_T_cam0_3) * R1^T.
  Eigen::Isometry3d rect_T_cam0 = Eigen::Isometry3d::Identity();
  rect_T_cam0.linear() = model.rectified_R_left;
  const Eigen::Isometry3d truth =
    rect_T_cam0 * world_T_camera2.inverse() * world_T_camera3 * rect_T_cam0.inverse();

  nlohmann::json json;
  json["sequence"] = "euroc_v1_01_pairs 2 -> 3";
  json["features"] = {features[0].size(), features[1].size()};
  json["correspondences"] = result.correspondences;
  json["inliers"] = result.inliers;
  json["epipolar_refined"] = result.epipolar_refined;
  json["valid"] = result.valid;
  json["reason"] = result.reason;
  json["gt_translation_m"] = truth.translation().norm();
  json["gt_rotation_deg"] = Eigen::AngleAxisd(truth.linear()).angle() * 180.0 / M_PI;
  json["feature_extraction_and_stereo_matching_ms"] = mean(feature_ms);
  json["odometry_ms"] = odometry_ms;
  if (result.valid) {
    const Eigen::Isometry3d estimate = result.previous_T_current;
    json["estimated_translation_m"] = estimate.translation().norm();
    json["estimated_rotation_deg"] =
      Eigen::AngleAxisd(estimate.linear()).angle() * 180.0 / M_PI;
    const Eigen::Isometry3d error = truth.inverse() * estimate;
    json["translation_error_m"] = error.translation().norm();
    json["rotation_error_deg"] =
      Eigen::AngleAxisd(error.linear()).angle() * 180.0 / M_PI;
    pcl::console::print_info(
      "EuRoC 2 -> 3: %zu matches, %zu inliers; GT |t| %.3f m, %.2f deg; estimated "
      "|t| %.3f m, %.2f deg; error %.3f m, %.2f deg [odometry %.1f ms]\n",
      result.correspondences, result.inliers, json["gt_translation_m"].get<double>(),
      json["gt_rotation_deg"].get<double>(),
      json["estimated_translation_m"].get<double>(),
      json["estimated_rotation_deg"].get<double>(),
      json["translation_error_m"].get<double>(),
      json["rotation_error_deg"].get<double>(), odometry_ms);
  } else {
    pcl::console::print_warn("EuRoC 2 -> 3: odometry invalid: %s\n",
                             result.reason.c_str());
  }
  return json;
}

int
run(int argc, char** argv)
{
  {
    if (pcl::console::find_switch(argc, argv, "-h")
        || pcl::console::find_switch(argc, argv, "--help")) {
      printHelp(argv[0]);
      return EXIT_SUCCESS;
    }
    planar_grid::cli::checkArguments(
      argc, argv,
      {"--sequence", "--data", "--features", "--max_features", "--max_range_m",
       "--output", "--threshold_m", "--reference_depth_m", "--ins_lever_arm_m",
       "--disparity_offset_px", "--disparity_offset_memory",
       "--disparity_offset_sigma_px"},
      {"--no_reprojection", "--no_epipolar", "--step_analysis",
       "--no_disparity_offset"});
    std::string sequence, data_dir = "../shared/data", features_name = "sift", output;
    if (pcl::console::parse_argument(argc, argv, "--sequence", sequence) < 0) {
      printHelp(argv[0]);
      pcl::console::print_error("--sequence is required\n");
      return EXIT_FAILURE;
    }
    pcl::console::parse_argument(argc, argv, "--data", data_dir);
    pcl::console::parse_argument(argc, argv, "--features", features_name);
    pcl::console::parse_argument(argc, argv, "--output", output);
    // An option given without a parseable number is an error; an absent one keeps the
    // default.
    const auto optionalNumber = [argc, argv](const char* name, auto& value) {
      if (pcl::console::find_switch(argc, argv, name)
          && pcl::console::parse_argument(argc, argv, name, value) < 0) {
        pcl::console::print_error("%s needs a number\n", name);
        return false;
      }
      return true;
    };
    StereoOdometry::Params odometry_params;
    if (!optionalNumber("--threshold_m", odometry_params.distance_threshold_m)
        || !optionalNumber("--reference_depth_m", odometry_params.reference_depth_m)
        || !optionalNumber("--disparity_offset_px", odometry_params.disparity_offset_px)
        || !optionalNumber("--disparity_offset_memory",
                           odometry_params.disparity_offset_memory)
        || !optionalNumber("--disparity_offset_sigma_px",
                           odometry_params.disparity_offset_sigma_px))
      return EXIT_FAILURE;
    odometry_params.estimate_disparity_offset =
      !pcl::console::find_switch(argc, argv, "--no_disparity_offset");
    const bool reprojection =
      !pcl::console::find_switch(argc, argv, "--no_reprojection");
    odometry_params.epipolar_refinement =
      !pcl::console::find_switch(argc, argv, "--no_epipolar");
    std::vector<double> lever_arm_m;
    if (pcl::console::find_switch(argc, argv, "--ins_lever_arm_m")
        && (pcl::console::parse_x_arguments(argc, argv, "--ins_lever_arm_m",
                                            lever_arm_m)
              < 0
            || lever_arm_m.size() != 2)) {
      pcl::console::print_error("--ins_lever_arm_m needs two numbers: F,L\n");
      return EXIT_FAILURE;
    }
    StereoFeatureMatcher::Params matcher_params;
    matcher_params.feature_type = planar_grid::featureTypeFromString(features_name);
    if (!optionalNumber("--max_features", matcher_params.max_features)
        || !optionalNumber("--max_range_m", matcher_params.max_range_m))
      return EXIT_FAILURE;
    const StereoFeatureMatcher matcher(matcher_params);
    pcl::console::print_info(
      "Sequence %s, data %s, features %s, RANSAC threshold %.3f m, reference depth "
      "%.1f m, ratio %.2f, mutual check %s, max_iterations %d, min_inliers %d, "
      "reprojection refinement %s, epipolar refinement %s, disparity offset %s "
      "(prior %.2f px)\n",
      sequence.c_str(), data_dir.c_str(), features_name.c_str(),
      odometry_params.distance_threshold_m, odometry_params.reference_depth_m,
      odometry_params.ratio, odometry_params.mutual_check ? "on" : "off",
      odometry_params.max_iterations, odometry_params.min_inliers,
      reprojection ? "on" : "off",
      reprojection && odometry_params.epipolar_refinement ? "on" : "off",
      reprojection && odometry_params.estimate_disparity_offset ? "estimated" : "fixed",
      odometry_params.disparity_offset_px);

    nlohmann::json json;
    if (sequence == "karlsruhe")
      json = runKarlsruhe(data_dir, matcher, odometry_params, reprojection, lever_arm_m,
                          pcl::console::find_switch(argc, argv, "--step_analysis"));
    else if (sequence == "kitti")
      json = runKitti(data_dir, matcher, odometry_params, reprojection);
    else if (sequence == "euroc")
      json = runEuroc(data_dir, matcher, odometry_params, reprojection);
    else {
      pcl::console::print_error("Unknown --sequence '%s' (karlsruhe, kitti, euroc)\n",
                                sequence.c_str());
      return EXIT_FAILURE;
    }
    json["features_type"] = features_name;
    json["max_features"] = matcher_params.max_features;
    json["max_range_m"] = matcher_params.max_range_m;
    json["ransac_distance_threshold_m"] = odometry_params.distance_threshold_m;
    json["reference_depth_m"] = odometry_params.reference_depth_m;
    json["reprojection_refinement"] = reprojection;
    json["epipolar_refinement"] = reprojection && odometry_params.epipolar_refinement;
    json["disparity_offset_estimated"] =
      reprojection && odometry_params.estimate_disparity_offset;
    json["disparity_offset_prior_px"] = odometry_params.disparity_offset_px;
    if (!output.empty()) {
      planar_grid::writeTextFileAtomically(output, json.dump(2) + "\n");
      pcl::console::print_info("Wrote %s\n", output.c_str());
    }
    return EXIT_SUCCESS;
  }
}

} // namespace

int
main(int argc, char** argv)
{
  return planar_grid::cli::runMain("planar_grid_odometry_eval", run, argc, argv);
}
