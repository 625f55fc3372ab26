// SPDX-License-Identifier: BSD-3-Clause
// The files of a SyntheticStereoScene sequence: the rectified PNG pairs, calibration,
// trajectory, truth cloud and the pipeline configuration that maps them.
#include <planar_grid/core/atomic_file.h>
#include <planar_grid/core/exceptions.h>
#include <planar_grid/odometry/trajectory_io.h>
#include <planar_grid/pipeline/pipeline_config.h>
#include <planar_grid/pipeline/pipeline_config_writer.h>
#include <planar_grid/visualization/synthetic_stereo_scene.h>

#include <pcl/io/pcd_io.h>

#include <nlohmann/json.hpp>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>

#include <algorithm>
#include <charconv>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>
#include <utility>
#include <variant>
#include <vector>

namespace planar_grid {

namespace {

namespace fs = std::filesystem;

/** \brief Spacing of the truth cloud written by writeSequence(), metres. */
constexpr double TRUTH_SPACING_M = 0.02;

/** \brief A number in shortest round-trip form for text files (std::to_chars: reads
 * back as the same double). */
std::string
exact(double value)
{
  char buffer[64];
  const auto result = std::to_chars(buffer, buffer + sizeof(buffer), value);
  return std::string(buffer, result.ptr);
}

/** \brief Writes \a bytes to \a path atomically. */
void
writeBytesAtomically(const std::string& path, const std::vector<unsigned char>& bytes)
{
  writeFileAtomically(path, [&bytes](const std::string& tmp) {
    std::ofstream out(tmp, std::ios::binary | std::ios::trunc);
    out.write(reinterpret_cast<const char*>(bytes.data()),
              static_cast<std::streamsize>(bytes.size()));
    out.flush();
    return static_cast<bool>(out);
  });
}

/** \brief Writes a grey image as PNG atomically (cv::imwrite picks the encoder from
 * the extension, which the temporary name lacks, so the PNG is encoded first). */
void
writePNG(const std::string& path, const cv::Mat& image)
{
  std::vector<unsigned char> png;
  if (!cv::imencode(".png", image, png))
    throw IOError(path + ": cannot encode the image as PNG");
  writeBytesAtomically(path, png);
}

} // namespace

std::string
SyntheticStereoScene::pipelineYaml(const std::string& output_folder) const
{
  const bool corridor = params_.kind == SyntheticSceneKind::CORRIDOR;
  // The far wall is up to 19 m (corridor) or 7 m (room) ahead; the stereo depth error
  // f B / d^2 * 0.5 px is 0.2 m at 12 m.
  const double range_m = corridor ? 12.0 : 10.0;
  // Indoors the walls beside the camera come close: 256 disparities see down to
  // f B / 256 = 1.44 m (128: 2.9 m). Nearer surfaces match wrongly into a fan of far
  // points; larger speckle windows and a stricter uniqueness remove most of them
  // (docs/SYNTHETIC_SCENE.md).
  const int disparities = 256;

  PipelineConfig config;
  InputConfig& input = config.input;
  input.type = InputConfig::Type::STEREO_SEQUENCE;
  input.left_images = "left/%06d.png";
  input.right_images = "right/%06d.png";
  input.first_index = 0;
  input.frame_count = params_.frame_count;
  input.calibration_format = CalibrationFormat::KARLSRUHE;
  input.calibration_file = "calib.txt";
  input.poses_format = PoseFormat::KITTI;
  input.poses_file = "poses.txt";

  // The stages of config/karlsruhe.yaml, with ranges for an indoor scene.
  using Value = std::variant<double, int, bool, std::string>;
  const auto stage =
    [&config](const std::string& type,
              const std::vector<std::pair<std::string, Value>>& params) {
      StageConfig s = defaultStageConfig(type);
      for (const auto& [key, value] : params)
        s.params.set(key, value);
      config.stages.push_back(std::move(s));
    };
  stage("stereo_disparity", {{"num_disparities_px", disparities},
                             {"block_size_px", 5},
                             {"uniqueness_ratio_percent", 15},
                             {"speckle_window_size_px", 400},
                             {"speckle_range_px", 2},
                             {"max_range_m", range_m}});
  stage("feature_matching", {{"feature_type", std::string("sift")},
                             {"max_features", 2000},
                             {"max_disparity_px", disparities},
                             {"max_range_m", range_m}});
  stage("kl_occupancy_filter", {{"update_rule", std::string("kl_divergence")},
                                {"disparity_error_px", 0.5},
                                {"neighbourhood_size_m", 0.5}});
  stage("voxel_grid", {{"leaf_size_m", 0.1}});
  stage("statistical_outlier_removal", {{"mean_k", 20}, {"stddev_mul_thresh", 2.0}});
  stage("transform_to_world", {});
  stage("multi_plane_segmentation", {{"distance_threshold_m", 0.05},
                                     {"sample_distance_threshold_m", 0.15},
                                     {"max_planes", 8},
                                     {"min_inliers", 150},
                                     {"sample", std::string("features")}});
  stage("ground_removal", {{"eps_angle_rad", 0.2}, {"min_sensor_height_m", 0.5}});
  stage("planar_cuboid_approximation", {{"min_cell_size_m", 0.1},
                                        {"density_threshold", 0.9},
                                        {"min_width_m", 0.1},
                                        {"min_height_m", 0.1},
                                        {"thickness_m", 0.1},
                                        {"min_points_per_cell", 3}});
  stage("map_integration", {{"resolution_m", 0.1},
                            {"max_range_m", range_m},
                            {"prior", std::string("free")},
                            {"thickness_m", 0.1}});
  stage("accumulate", {{"leaf_size_m", 0.1}, {"downsample_every_n_frames", 5}});

  config.output.folder = output_folder;
  config.output.snapshot_camera = "oblique";

  std::ostringstream comment;
  comment << "Synthetic " << toString(params_.kind)
          << " (planar_grid::SyntheticStereoScene, planar_grid_render_scene): "
          << params_.frame_count << " frames, step " << exact(params_.step_m)
          << " m, scene yaw " << exact(params_.scene_yaw_rad) << " rad, wall lean "
          << exact(params_.wall_lean_rad) << " rad, seed " << params_.seed << ".\n"
          << "Rectified grey stereo " << params_.width_px << "x" << params_.height_px
          << ", f = " << exact(params_.focal_length_px)
          << " px, B = " << exact(params_.baseline_m)
          << " m; true poses in poses.txt; true surfaces in scene.json and truth.pcd.\n"
          << "Stages as config/karlsruhe.yaml, ranges for an indoor scene; parameters "
             "not\nlisted take their defaults (planar_grid_pipeline --list-stages). "
             "Schema:\nconfig/example.yaml.\n\n"
          << "  planar_grid_pipeline --config pipeline.yaml";
  return pipelineConfigToYaml(config, comment.str());
}

void
SyntheticStereoScene::writeSequence(const std::string& folder)
{
  const fs::path root(folder);
  std::error_code ec;
  for (const char* sub : {"left", "right"}) {
    fs::create_directories(root / sub, ec);
    if (ec)
      throw IOError((root / sub).string()
                    + ": cannot create the folder: " + ec.message());
  }

  // Images.
  for (std::size_t i = 0; i < getFrameCount(); ++i) {
    cv::Mat left, right;
    render(i, left, right);
    char name[32];
    std::snprintf(name, sizeof(name), "%06zu.png", i);
    writePNG((root / "left" / name).string(), left);
    writePNG((root / "right" / name).string(), right);
  }

  // Calibration, Karlsruhe format: the rectified projection matrices of the cropped
  // images (P1_roi, P2_roi; P2_roi(0,3) = -f B).
  const double f = calibration_.focal_length_px, cx = calibration_.cx_px,
               cy = calibration_.cy_px, b = calibration_.baseline_m;
  std::ostringstream calib;
  calib << "calib_time: synthetic (planar_grid::SyntheticStereoScene, "
        << toString(params_.kind) << ", seed " << params_.seed << ")\n";
  const auto row = [&](const char* key, double tx) {
    calib << key << " " << exact(f) << " 0 " << exact(cx) << " " << exact(tx) << " 0 "
          << exact(f) << " " << exact(cy) << " 0 0 0 1 0\n";
  };
  row("P1:", 0.0);
  row("P1_roi:", 0.0);
  row("P2:", -f * b);
  row("P2_roi:", -f * b);
  writeTextFileAtomically((root / "calib.txt").string(), calib.str());

  // Poses.
  Trajectory poses;
  for (std::size_t i = 0; i < getFrameCount(); ++i)
    poses.push_back(getCameraPose(i));
  saveKittiPoses((root / "poses.txt").string(), poses);

  // Truth cloud.
  pcl::PointCloud<pcl::PointXYZ> truth;
  samplePoints(TRUTH_SPACING_M, truth);
  writeFileAtomically((root / "truth.pcd").string(), [&truth](const std::string& tmp) {
    pcl::PCDWriter writer;
    return writer.writeBinary(tmp, truth) == 0;
  });

  // Scene description.
  nlohmann::json scene;
  scene["generator"] = "planar_grid::SyntheticStereoScene";
  scene["scene"] = toString(params_.kind);
  scene["scene_yaw_rad"] = params_.scene_yaw_rad;
  scene["wall_lean_rad"] = params_.wall_lean_rad;
  scene["frame_count"] = params_.frame_count;
  scene["step_m"] = params_.step_m;
  scene["camera_height_m"] = params_.camera_height_m;
  scene["texel_m"] = params_.texel_m;
  scene["seed"] = params_.seed;
  scene["calibration"] = {{"focal_length_px", f},
                          {"cx_px", cx},
                          {"cy_px", cy},
                          {"baseline_m", b},
                          {"width_px", params_.width_px},
                          {"height_px", params_.height_px}};
  scene["files"] = {
    {"left_images", "left/%06d.png"}, {"right_images", "right/%06d.png"},
    {"calibration", "calib.txt"},     {"poses", "poses.txt"},
    {"truth_cloud", "truth.pcd"},     {"truth_spacing_m", TRUTH_SPACING_M},
    {"pipeline", "pipeline.yaml"}};
  nlohmann::json planes = nlohmann::json::array();
  for (const auto& plane : planes_) {
    nlohmann::json polygon = nlohmann::json::array();
    for (const auto& c : plane.polygon)
      polygon.push_back({c.x(), c.y(), c.z()});
    planes.push_back({{"name", plane.name},
                      {"model_coefficients",
                       {plane.model_coefficients[0], plane.model_coefficients[1],
                        plane.model_coefficients[2], plane.model_coefficients[3]}},
                      {"tilt_rad", plane.tilt_rad},
                      {"polygon", polygon}});
  }
  scene["planes"] = planes;
  writeTextFileAtomically((root / "scene.json").string(), scene.dump(2) + "\n");

  // The pipeline, writing next to the sequence wherever it is run from.
  const fs::path output = fs::absolute(root / "output", ec).lexically_normal();
  writeTextFileAtomically(
    (root / "pipeline.yaml").string(),
    pipelineYaml(ec ? (root / "output").string() : output.string()));
}

} // namespace planar_grid
