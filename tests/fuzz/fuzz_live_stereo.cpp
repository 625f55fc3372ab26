// SPDX-License-Identifier: BSD-3-Clause
// libFuzzer target: a stereo frame as the ROS node receives it. Two sensor_msgs/Image
// and two sensor_msgs/CameraInfo of any content (sizes, steps and encodings that may
// disagree with the data, projection matrices of any values, plausible ones too)
// go through the node's own conversions (ros_messages::greyImage,
// ros_messages::calibrationFromCameraInfo) into Mapper::integrateStereo of a small
// live pipeline (SGBM, features, KL filter, voxel grid, planes, cuboids, map). The
// contract: the frame is mapped, or a planar_grid::Exception names the cause; a signal,
// a sanitizer report, an OpenCV assertion or any other exception is a finding.

#include <planar_grid/core/exceptions.h>
#include <planar_grid/pipeline/mapper.h>
#include <planar_grid/pipeline/pipeline_config.h>
#include <planar_grid/ros_bag/ros_messages.h>

#include <pcl/console/print.h>

#include <Eigen/Geometry>
#include <fuzzer/FuzzedDataProvider.h>
#include <opencv2/core/mat.hpp>

#include <algorithm>
#include <array>
#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <memory>
#include <string>
#include <vector>

namespace {

namespace fs = std::filesystem;

/** The Mapper every input goes to, with the files its configuration names (never read
 * by a Mapper, but the configuration must name them) in a temporary folder. */
struct Job {
  fs::path dir;
  std::unique_ptr<planar_grid::Mapper> mapper;

  Job()
  {
    dir = fs::temp_directory_path() / "planar_grid_fuzz_live_stereo";
    fs::create_directories(dir);
    std::ofstream(dir / "calib.txt") << "P0: 500 0 32 0 0 500 24 0 0 0 1 0\n"
                                        "P1: 500 0 32 -250 0 500 24 0 0 0 1 0\n";
    std::ofstream(dir / "poses.txt") << "1 0 0 0 0 1 0 0 0 0 1 0\n";
    const std::string d = dir.string();
    const auto config = planar_grid::parsePipelineConfig(
      "input:\n  type: stereo_sequence\n  left_images: " + d
        + "/l_%06d.png\n  right_images: " + d
        + "/r_%06d.png\n  calibration: {format: kitti, file: " + d
        + "/calib.txt}\n  poses: {format: kitti, file: " + d
        + "/poses.txt}\npipeline:\n"
          "  - type: stereo_disparity\n"
          "    params: {num_disparities_px: 16, block_size_px: 3}\n"
          "  - type: feature_matching\n  - type: kl_occupancy_filter\n"
          "  - type: voxel_grid\n  - type: transform_to_world\n"
          "  - type: multi_plane_segmentation\n"
          "  - type: planar_cuboid_approximation\n  - type: map_integration\n",
      "fuzz_live_stereo.yaml", "/");
    mapper = std::make_unique<planar_grid::Mapper>(planar_grid::toMapperConfig(config));
  }
  ~Job()
  {
    mapper.reset();
    std::error_code ec;
    fs::remove_all(dir, ec);
  }
};

/** \a size bytes of image data: the fuzzer's bytes, then a texture seeded by one more
 * byte that the feature matcher finds features in. */
std::vector<std::uint8_t>
pixels(FuzzedDataProvider& in, std::size_t size)
{
  std::vector<std::uint8_t> data = in.ConsumeBytes<std::uint8_t>(size);
  const std::uint8_t seed = in.ConsumeIntegral<std::uint8_t>();
  for (std::size_t k = data.size(); k < size; ++k)
    data.push_back(static_cast<std::uint8_t>((k * 2654435761u + seed) >> 13));
  return data;
}

/** An image message: most of the time of the cameras' size (96 x 48, so that the
 * frame can be mapped), else of a small or of any size; an encoding of the node's list
 * or any text; a step and data that may not match. */
sensor_msgs::Image
image(FuzzedDataProvider& in)
{
  sensor_msgs::Image msg;
  switch (in.ConsumeIntegralInRange<int>(0, 3)) {
    case 0:
    case 1:
      msg.height = 48;
      msg.width = 96;
      break;
    case 2:
      msg.height = in.ConsumeIntegralInRange<std::uint32_t>(0, 48);
      msg.width = in.ConsumeIntegralInRange<std::uint32_t>(0, 96);
      break;
    default:
      msg.height = in.ConsumeIntegral<std::uint32_t>();
      msg.width = in.ConsumeIntegral<std::uint32_t>();
  }
  static const std::array<const char*, 9> encodings = {
    "mono8", "8UC1", "bgr8", "rgb8", "bgra8", "rgba8", "mono16", "16UC1", "32FC1"};
  msg.encoding = in.ConsumeBool() ? std::string(in.PickValueInArray(encodings))
                                  : in.ConsumeRandomLengthString(16);
  msg.is_bigendian = in.ConsumeIntegral<std::uint8_t>();
  const std::uint32_t channels = msg.encoding == "bgr8" || msg.encoding == "rgb8" ? 3
                                 : msg.encoding == "bgra8" || msg.encoding == "rgba8"
                                   ? 4
                                   : 1;
  msg.step =
    in.ConsumeBool() ? msg.width * channels : in.ConsumeIntegral<std::uint32_t>();
  const std::size_t wanted =
    static_cast<std::size_t>(msg.step) * static_cast<std::size_t>(msg.height);
  const std::size_t size = in.ConsumeBool() && wanted <= 48 * 96 * 4
                             ? wanted
                             : in.ConsumeIntegralInRange<std::size_t>(0, 48 * 96 * 4);
  msg.data = pixels(in, size);
  return msg;
}

/** The two CameraInfo messages of a pair: the P of a rectified pair (f, cx, cy and the
 * right camera's Tx = -f B) of plausible or absurd values, or any twelve numbers each;
 * the images' size or any. */
void
cameraInfos(FuzzedDataProvider& in,
            sensor_msgs::CameraInfo& left,
            sensor_msgs::CameraInfo& right)
{
  for (auto* msg : {&left, &right}) {
    const bool images = in.ConsumeBool() || in.ConsumeBool();
    msg->width = images ? 96 : in.ConsumeIntegral<std::uint32_t>();
    msg->height = images ? 48 : in.ConsumeIntegral<std::uint32_t>();
  }
  if (in.ConsumeBool() || in.ConsumeBool()) {
    const double f = in.ConsumeFloatingPointInRange<double>(-10.0, 2000.0);
    const double cx = in.ConsumeFloatingPointInRange<double>(-100.0, 200.0);
    const double cy = in.ConsumeFloatingPointInRange<double>(-100.0, 200.0);
    const double baseline = in.ConsumeBool()
                              ? in.ConsumeFloatingPointInRange<double>(0.01, 1.0)
                              : in.ConsumeFloatingPoint<double>();
    left.P = {f, 0.0, cx, 0.0, 0.0, f, cy, 0.0, 0.0, 0.0, 1.0, 0.0};
    right.P = {f, 0.0, cx, -f * baseline, 0.0, f, cy, 0.0, 0.0, 0.0, 1.0, 0.0};
  } else {
    for (auto* msg : {&left, &right})
      for (auto& p : msg->P)
        p = in.ConsumeFloatingPoint<double>();
  }
}

} // namespace

namespace {

/** Inputs mapped and refused, printed at exit with PLANAR_GRID_FUZZ_STATS set: how
 * many inputs reach the pipeline's stages. */
std::size_t mapped = 0, refused = 0;
/** PLANAR_GRID_FUZZ_STATS=verbose: also every refusal's message. */
bool verbose = false;

void
printStats()
{
  std::fprintf(stderr, "fuzz_live_stereo: %zu inputs mapped, %zu refused\n", mapped,
               refused);
}

} // namespace

extern "C" int
LLVMFuzzerInitialize(int* /*argc*/, char*** /*argv*/)
{
  if (const char* stats = std::getenv("PLANAR_GRID_FUZZ_STATS")) {
    verbose = std::string(stats) == "verbose";
    std::atexit(printStats);
  }
  // The pipeline warns about frames without points: silenced, so that the fuzzer's
  // time goes to the inputs.
  pcl::console::setVerbosityLevel(pcl::console::L_ALWAYS);
  return 0;
}

extern "C" int
LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size)
{
  static const Job job;
  FuzzedDataProvider in(data, size);
  sensor_msgs::CameraInfo left_info, right_info;
  sensor_msgs::Image left_msg, right_msg;
  // One input in 16 is a camera's good frame (mono8 96 x 48, the right image the left
  // one shifted by a few pixels, a rectified calibration) whose pixels, shift and
  // calibration the fuzzer varies, so that frames reach the pipeline's stages; the
  // others are messages of any content.
  if (in.ConsumeIntegralInRange<int>(0, 15) == 0) {
    for (auto* msg : {&left_msg, &right_msg}) {
      msg->height = 48;
      msg->width = 96;
      msg->encoding = "mono8";
      msg->step = 96;
    }
    left_msg.data = pixels(in, 48 * 96);
    const int shift = in.ConsumeIntegralInRange<int>(2, 15);
    right_msg.data.resize(48 * 96);
    for (int v = 0; v < 48; ++v)
      for (int u = 0; u < 96; ++u)
        right_msg.data[static_cast<std::size_t>(v * 96 + u)] =
          left_msg.data[static_cast<std::size_t>(v * 96 + std::min(95, u + shift))];
    for (auto* msg : {&left_info, &right_info}) {
      msg->width = 96;
      msg->height = 48;
    }
    const double f = in.ConsumeFloatingPointInRange<double>(100.0, 1000.0);
    const double cx = in.ConsumeFloatingPointInRange<double>(40.0, 56.0);
    const double cy = in.ConsumeFloatingPointInRange<double>(20.0, 28.0);
    const double baseline = in.ConsumeFloatingPointInRange<double>(0.01, 2.0);
    left_info.P = {f, 0.0, cx, 0.0, 0.0, f, cy, 0.0, 0.0, 0.0, 1.0, 0.0};
    right_info.P = {f, 0.0, cx, -f * baseline, 0.0, f, cy, 0.0, 0.0, 0.0, 1.0, 0.0};
  } else {
    cameraInfos(in, left_info, right_info);
    left_msg = image(in);
    right_msg = in.ConsumeBool() ? left_msg : image(in); // one image given twice
  }
  try {
    const cv::Mat left = planar_grid::ros_messages::greyImage(left_msg, "left image");
    const cv::Mat right =
      planar_grid::ros_messages::greyImage(right_msg, "right image");
    const planar_grid::StereoCalibration calibration =
      planar_grid::ros_messages::calibrationFromCameraInfo(left_info, right_info,
                                                           "right camera_info");
    job.mapper->integrateStereo(left, right, calibration,
                                Eigen::Isometry3d::Identity());
    ++mapped;
  } catch (const planar_grid::Exception& e) {
    ++refused;
    if (verbose)
      std::fprintf(stderr, "refused: %s\n", e.what());
  }
  // Every input starts from an empty map: the map stays small, and the first frame's
  // checks (the principal point, the pair's order) run on every input.
  job.mapper->reset();
  return 0;
}
