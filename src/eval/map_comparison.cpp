// SPDX-License-Identifier: BSD-3-Clause
// The paper's comparison (Sec. IV-B, Figs. 12-14): SG, OG, RA and PG on the same frames
// at several minimum cell sizes, in one process.
#include <planar_grid/core/atomic_file.h>
#include <planar_grid/core/exceptions.h>
#include <planar_grid/eval/map_comparison.h>
#include <planar_grid/eval/mapping_error.h>
#include <planar_grid/eval/rectangular_cuboid_approximation.h>
#include <planar_grid/eval/standard_voxel_grid.h>
#include <planar_grid/pipeline/frame_source.h>
#include <planar_grid/pipeline/stage.h>

#include <pcl/common/transforms.h>
#include <pcl/io/pcd_io.h>

#include <octomap/octomap.h>
#include <opencv2/imgcodecs.hpp>
#include <yaml-cpp/yaml.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <filesystem>
#include <iomanip>
#include <map>
#include <memory>
#include <set>
#include <sstream>
#include <unordered_map>

namespace planar_grid {

namespace {

namespace fs = std::filesystem;

/** Strict YAML access with file:line:col errors (the evaluation's small schema). */
class Reader {
public:
  explicit Reader(std::string file) : file_(std::move(file)) {}

  [[noreturn]] void fail(const YAML::Node& node, const std::string& message) const
  {
    const YAML::Mark mark = node.Mark();
    throw ConfigError(file_, mark.is_null() ? 0 : mark.line + 1,
                      mark.is_null() ? 0 : mark.column + 1, message);
  }

  void checkKeys(const YAML::Node& node,
                 const std::vector<std::string>& allowed,
                 const std::string& what) const
  {
    if (!node.IsMap())
      fail(node, what + " must be a map of key: value");
    std::set<std::string> seen;
    for (const auto& item : node) {
      if (!item.first.IsScalar())
        fail(item.first, "a key in " + what + " must be a plain name");
      const std::string key = item.first.as<std::string>();
      if (!seen.insert(key).second)
        fail(item.first, "key '" + key + "' is given twice in " + what);
      if (std::find(allowed.begin(), allowed.end(), key) == allowed.end()) {
        std::string list;
        for (const auto& a : allowed)
          list += (list.empty() ? "" : ", ") + a;
        fail(item.first, "unknown key '" + key + "' in " + what
                           + " (expected one of: " + list + ")");
      }
    }
  }

  std::string string(const YAML::Node& parent,
                     const std::string& key,
                     const std::string& what) const
  {
    const YAML::Node node = parent[key];
    if (!node)
      fail(parent, what + " needs the key '" + key + "'");
    if (!node.IsScalar())
      fail(node, what + "." + key + " must be a string");
    return node.as<std::string>();
  }

  double
  real(const YAML::Node& node, double lo, double hi, const std::string& what) const
  {
    double v = 0.0;
    try {
      v = node.as<double>();
    } catch (const YAML::BadConversion&) {
      fail(node, what + " must be a number");
    }
    if (!std::isfinite(v) || v < lo || v > hi)
      fail(node, what + " must be in [" + std::to_string(lo) + ", " + std::to_string(hi)
                   + "]");
    return v;
  }

  std::size_t count(const YAML::Node& node, long long lo, const std::string& what) const
  {
    long long v = -1;
    try {
      v = node.as<long long>();
    } catch (const YAML::BadConversion&) {
      fail(node, what + " must be an integer");
    }
    if (v < lo || v > 100000000)
      fail(node, what + " must be an integer >= " + std::to_string(lo));
    return static_cast<std::size_t>(v);
  }

  /** A path relative to the configuration file's folder. */
  std::string path(const std::string& text) const
  {
    const fs::path p(text);
    if (p.is_absolute())
      return p.string();
    return (fs::path(file_).parent_path() / p).lexically_normal().string();
  }

private:
  std::string file_;
};

/** The stages that do not depend on the cell size: run once per frame. */
bool
isFrontEnd(const std::string& type)
{
  return type == "stereo_disparity" || type == "feature_matching"
         || type == "kl_occupancy_filter" || type == "visual_odometry";
}

/** The pipeline stage \a sc with every size parameter set to \a r. */
std::unique_ptr<Stage>
createAtResolution(const StageConfig& sc, double r)
{
  const StageInfo* info = findStage(sc.type);
  if (!info)
    throw Exception("unknown stage type '" + sc.type + "'");
  ParamValues params = sc.params;
  const auto has = [&params](const std::string& key) {
    return params.values().count(key) > 0;
  };
  for (const char* key : {"leaf_size_m", "min_cell_size_m", "min_width_m",
                          "min_height_m", "resolution_m", "thickness_m"})
    if (has(key) && sc.type != "statistical_outlier_removal")
      params.set(key, r);
  if (sc.type == "multi_plane_segmentation" && has("min_inliers")) {
    // The same surface area: the voxel count falls with the square of the cell size.
    const double scaled = params.getInt("min_inliers") * (0.1 / r) * (0.1 / r);
    params.set("min_inliers", std::max(10, static_cast<int>(std::lround(scaled))));
  }
  return info->create(params);
}

double
msSince(std::chrono::steady_clock::time_point t)
{
  return std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t)
    .count();
}

/** The valid points of \a cloud in the world frame (transformed by the frame's pose
 * when the cloud is still in the camera frame). */
pcl::PointCloud<pcl::PointXYZ>
worldPoints(const Frame& frame)
{
  pcl::PointCloud<pcl::PointXYZ> out;
  if (!frame.cloud)
    return out;
  Eigen::Matrix4f world_T = Eigen::Matrix4f::Identity();
  if (!frame.cloud_in_world_frame)
    world_T = frame.world_T_camera.matrix().cast<float>();
  out.reserve(frame.cloud->size());
  for (const auto& p : frame.cloud->points) {
    if (!std::isfinite(p.x) || !std::isfinite(p.y) || !std::isfinite(p.z))
      continue;
    const Eigen::Vector4f q = world_T * Eigen::Vector4f(p.x, p.y, p.z, 1.0f);
    out.push_back(pcl::PointXYZ(q.x(), q.y(), q.z()));
  }
  return out;
}

/** The REFERENCE truth: voxels of all frames' points with the number of frames that
 * saw each. */
class ReferenceVoxels {
public:
  explicit ReferenceVoxels(double leaf_m) : leaf_m_(leaf_m) {}

  void addFrame(const pcl::PointCloud<pcl::PointXYZ>& points)
  {
    ++frame_;
    for (const auto& p : points.points) {
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
  std::uint32_t frame_{0};
  std::unordered_map<std::uint64_t, Voxel> voxels_;
};

/** One cell size: the back-end stages and state of PG, and the SG and OG maps. */
struct Lane {
  double resolution_m{0.1};
  std::vector<std::unique_ptr<Stage>> stages;
  std::vector<std::string> types;
  PipelineState state;
  std::unique_ptr<StandardVoxelGrid> sg;
  std::unique_ptr<octomap::OcTree> og;
  double pg_ms{0.0}, sg_ms{0.0}, og_ms{0.0};
};

} // namespace

namespace {

ComparisonConfig
parseComparison(const YAML::Node& root, const std::string& path)
{
  const Reader r(path);
  ComparisonConfig config;
  config.source_file = path;
  r.checkKeys(root,
              {"environment", "resolutions_m", "tolerance_cells", "datasets", "output"},
              "the evaluation configuration");
  if (root["environment"]) {
    config.environment = r.string(root, "environment", "the configuration");
    if (config.environment != "indoor" && config.environment != "outdoor")
      r.fail(root["environment"], "environment must be indoor or outdoor");
  }
  if (const YAML::Node res = root["resolutions_m"]) {
    if (!res.IsSequence() || res.size() == 0)
      r.fail(res, "resolutions_m must be a non-empty list of cell sizes in meters");
    config.resolutions_m.clear();
    for (const auto& v : res)
      config.resolutions_m.push_back(r.real(v, 0.01, 10.0, "resolutions_m entries"));
  }
  if (root["tolerance_cells"])
    config.tolerance_cells =
      r.real(root["tolerance_cells"], 0.1, 10.0, "tolerance_cells");
  if (const YAML::Node out = root["output"]) {
    r.checkKeys(out, {"folder"}, "output");
    config.output_folder = r.string(out, "folder", "output");
  }
  const YAML::Node datasets = root["datasets"];
  if (!datasets || !datasets.IsSequence() || datasets.size() == 0)
    r.fail(datasets ? datasets : root, "datasets must be a non-empty list");
  for (const auto& node : datasets) {
    r.checkKeys(node, {"name", "pipeline", "frames", "truth", "tilt_deg"}, "a dataset");
    DatasetConfig ds;
    ds.name = r.string(node, "name", "a dataset");
    ds.pipeline_file = r.path(r.string(node, "pipeline", "dataset " + ds.name));
    ds.pipeline = loadPipelineConfig(ds.pipeline_file);
    if (const YAML::Node frames = node["frames"]) {
      r.checkKeys(frames, {"first", "count", "step"}, "dataset " + ds.name + ".frames");
      if (frames["first"])
        ds.first_frame = r.count(frames["first"], 0, "frames.first");
      if (frames["count"])
        ds.frame_count = r.count(frames["count"], 0, "frames.count");
      if (frames["step"])
        ds.frame_step = r.count(frames["step"], 1, "frames.step");
    }
    const YAML::Node truth = node["truth"];
    if (!truth)
      r.fail(node, "dataset " + ds.name
                     + " needs a truth (type: points, disparity or "
                       "reference)");
    r.checkKeys(truth, {"type", "file", "leaf_size_m", "min_views"},
                "dataset " + ds.name + ".truth");
    const std::string type = r.string(truth, "type", "truth");
    if (type == "points")
      ds.truth.type = TruthConfig::Type::POINTS;
    else if (type == "disparity")
      ds.truth.type = TruthConfig::Type::DISPARITY;
    else if (type == "reference")
      ds.truth.type = TruthConfig::Type::REFERENCE;
    else
      r.fail(truth["type"], "truth.type must be points, disparity or reference");
    if (ds.truth.type != TruthConfig::Type::REFERENCE)
      ds.truth.file = r.path(r.string(truth, "file", "truth"));
    else if (truth["file"])
      r.fail(truth["file"], "truth.file is not used by type reference");
    if (truth["leaf_size_m"])
      ds.truth.leaf_size_m =
        r.real(truth["leaf_size_m"], 0.005, 1.0, "truth.leaf_size_m");
    if (truth["min_views"])
      ds.truth.min_views = r.count(truth["min_views"], 1, "truth.min_views");
    if ((truth["leaf_size_m"] || truth["min_views"])
        && ds.truth.type != TruthConfig::Type::REFERENCE)
      r.fail(truth, "truth.leaf_size_m and truth.min_views are for type reference");
    if (node["tilt_deg"])
      ds.tilt_deg = r.real(node["tilt_deg"], 0.0, 90.0, "tilt_deg");
    // The front end comes first: the split into shared and per-size stages needs it.
    bool back = false;
    for (const auto& sc : ds.pipeline.stages) {
      if (!isFrontEnd(sc.type))
        back = true;
      else if (back)
        throw ConfigError(ds.pipeline_file, sc.line, sc.column,
                          "stage '" + sc.type
                            + "' must come before the cell-size stages for the "
                              "evaluation (it runs once per frame for all sizes)");
    }
    config.datasets.push_back(std::move(ds));
  }
  return config;
}

} // namespace

ComparisonConfig
loadComparisonConfig(const std::string& path)
{
  YAML::Node root;
  try {
    root = YAML::LoadFile(path);
  } catch (const YAML::BadFile&) {
    throw IOError(path + ": cannot be read");
  } catch (const YAML::ParserException& e) {
    throw ConfigError(path, e.mark.line + 1, e.mark.column + 1, e.msg);
  }
  try {
    return parseComparison(root, path);
  } catch (const YAML::Exception& e) {
    throw ConfigError(path, e.mark.is_null() ? 0 : e.mark.line + 1,
                      e.mark.is_null() ? 0 : e.mark.column + 1, e.msg);
  }
}

std::vector<ComparisonRow>
runComparison(const ComparisonConfig& config,
              const std::function<void(const std::string&)>& progress)
{
  using Clock = std::chrono::steady_clock;
  std::vector<ComparisonRow> rows;
  for (const auto& ds : config.datasets) {
    const auto source = createFrameSource(ds.pipeline.input);
    const std::size_t end =
      ds.frame_count > 0 ? std::min(source->size(), ds.first_frame + ds.frame_count)
                         : source->size();
    if (ds.first_frame >= end)
      throw Exception("dataset " + ds.name + ": no frames in the range");

    std::vector<std::unique_ptr<Stage>> front;
    std::vector<std::string> front_types;
    std::vector<Lane> lanes(config.resolutions_m.size());
    for (std::size_t k = 0; k < lanes.size(); ++k) {
      Lane& lane = lanes[k];
      lane.resolution_m = config.resolutions_m[k];
      for (const auto& sc : ds.pipeline.stages) {
        if (isFrontEnd(sc.type)) {
          if (k == 0) {
            front.push_back(createAtResolution(sc, lane.resolution_m));
            front_types.push_back(sc.type);
          }
          continue;
        }
        lane.stages.push_back(createAtResolution(sc, lane.resolution_m));
        lane.types.push_back(sc.type);
      }
      StandardVoxelGrid::Params sg;
      sg.resolution_m = lane.resolution_m;
      lane.sg = std::make_unique<StandardVoxelGrid>(sg);
      lane.og = std::make_unique<octomap::OcTree>(lane.resolution_m);
    }
    PipelineState front_state;
    for (auto& s : front)
      s->start(front_state);
    for (auto& lane : lanes)
      for (auto& s : lane.stages)
        s->start(lane.state);

    ReferenceVoxels reference(ds.truth.leaf_size_m);
    Frame first_frame;
    std::size_t frames = 0;
    for (std::size_t i = ds.first_frame; i < end; i += ds.frame_step) {
      Frame frame;
      source->load(i, frame);
      frame.sequence_number = i;
      double kl_ms = 0.0;
      for (std::size_t s = 0; s < front.size(); ++s) {
        const auto t = Clock::now();
        front[s]->process(frame, front_state);
        if (front_types[s] == "kl_occupancy_filter")
          kl_ms += msSince(t); // the occupancy of the features is PG's work
      }
      if (frames == 0)
        first_frame = frame;
      if (ds.truth.type == TruthConfig::Type::REFERENCE)
        reference.addFrame(worldPoints(frame));
      for (auto& lane : lanes) {
        Frame f = frame;
        if (frame.cloud)
          f.cloud.reset(new Frame::Cloud(*frame.cloud));
        lane.pg_ms += kl_ms;
        bool inserted = false;
        const auto insertBaselines = [&]() {
          // SG and OG get the cloud PG's approximation gets.
          const pcl::PointCloud<pcl::PointXYZ> points = worldPoints(f);
          const Eigen::Vector3f origin = f.world_T_camera.translation().cast<float>();
          auto t = Clock::now();
          lane.sg->insertPointCloud(points, origin);
          lane.sg_ms += msSince(t);
          t = Clock::now();
          octomap::Pointcloud scan;
          scan.reserve(points.size());
          for (const auto& p : points.points)
            scan.push_back(p.x, p.y, p.z);
          lane.og->insertPointCloud(
            scan, octomap::point3d(origin.x(), origin.y(), origin.z()));
          lane.og_ms += msSince(t);
          inserted = true;
        };
        for (std::size_t s = 0; s < lane.stages.size(); ++s) {
          if (lane.types[s] == "planar_cuboid_approximation")
            insertBaselines();
          const auto t = Clock::now();
          try {
            lane.stages[s]->process(f, lane.state);
          } catch (const Exception& e) {
            throw Exception("dataset " + ds.name + ", frame " + f.name + ", cell size "
                            + std::to_string(lane.resolution_m) + " m, stage '"
                            + lane.types[s] + "': " + e.what());
          }
          if (lane.types[s] != "accumulate")
            lane.pg_ms += msSince(t);
        }
        if (!inserted)
          insertBaselines();
      }
      ++frames;
    }
    for (auto& lane : lanes)
      for (auto& s : lane.stages)
        s->finish(lane.state);

    // The truth.
    pcl::PointCloud<pcl::PointXYZ>::Ptr truth_points(
      new pcl::PointCloud<pcl::PointXYZ>);
    std::string truth_kind = "truth";
    switch (ds.truth.type) {
      case TruthConfig::Type::POINTS:
        if (pcl::io::loadPCDFile(ds.truth.file, *truth_points) != 0)
          throw IOError(ds.truth.file + ": cannot read the truth points (PCD)");
        break;
      case TruthConfig::Type::DISPARITY: {
        const cv::Mat gt = cv::imread(ds.truth.file, cv::IMREAD_UNCHANGED);
        if (gt.empty() || gt.type() != CV_8UC1)
          throw IOError(ds.truth.file + ": not an 8-bit disparity image");
        const StereoCalibration& c = first_frame.calibration;
        const Eigen::Matrix4f world_T =
          first_frame.world_T_camera.matrix().cast<float>();
        for (int v = 0; v < gt.rows; ++v)
          for (int u = 0; u < gt.cols; ++u) {
            const int d = gt.at<std::uint8_t>(v, u);
            if (d == 0)
              continue;
            const double z = c.depthFromDisparity(d);
            const Eigen::Vector4f p(
              static_cast<float>((u - c.cx_px) * z / c.focal_length_px),
              static_cast<float>((v - c.cy_px) * z / c.focal_length_px),
              static_cast<float>(z), 1.0f);
            const Eigen::Vector4f q = world_T * p;
            truth_points->push_back(pcl::PointXYZ(q.x(), q.y(), q.z()));
          }
        break;
      }
      case TruthConfig::Type::REFERENCE:
        reference.getPoints(ds.truth.min_views, *truth_points);
        truth_kind = "reference";
        break;
    }
    if (truth_points->empty())
      throw Exception("dataset " + ds.name + ": the truth has no points");
    const GroundTruthSurface truth(truth_points);

    for (auto& lane : lanes) {
      const double r = lane.resolution_m;
      const double tolerance = config.tolerance_cells * r;
      const auto n = static_cast<double>(frames);
      ComparisonRow base;
      base.dataset = ds.name;
      base.environment = config.environment;
      base.resolution_m = r;
      base.frames = frames;
      base.tilt_deg = ds.tilt_deg;
      base.truth_kind = truth_kind;

      ComparisonRow sg = base;
      sg.method = "SG";
      sg.cells = lane.sg->getOccupiedCount();
      sg.all_cells = lane.sg->getVoxelCount();
      sg.memory_bytes = lane.sg->getMemoryBytes();
      sg.ms_per_frame = lane.sg_ms / n;
      const MappingError sg_error = evaluateVoxels(*lane.sg, truth, tolerance);
      sg.samples = sg_error.samples;
      sg.erroneous = sg_error.erroneous;

      ComparisonRow og = base;
      og.method = "OG";
      lane.og->prune();
      for (auto it = lane.og->begin_leafs(); it != lane.og->end_leafs(); ++it) {
        ++og.all_cells;
        og.cells += lane.og->isNodeOccupied(*it);
      }
      og.memory_bytes = lane.og->memoryUsage();
      og.ms_per_frame = lane.og_ms / n;
      const MappingError og_error = evaluateOcTree(*lane.og, truth, tolerance);
      og.samples = og_error.samples;
      og.erroneous = og_error.erroneous;

      ComparisonRow ra = base;
      ra.method = "RA";
      AxisAlignedBoxes boxes;
      const auto t = Clock::now();
      RectangularCuboidApproximation().compute(*lane.sg, boxes);
      // RA's map is built from the voxel grid: its time is SG's plus the merge, which
      // runs once here (spread over the frames).
      ra.ms_per_frame = (lane.sg_ms + msSince(t)) / n;
      for (const auto& b : boxes)
        ra.cells += b.occupied;
      ra.all_cells = boxes.size();
      ra.memory_bytes = RectangularCuboidApproximation::getMemoryBytes(boxes);
      const MappingError ra_error = evaluateBoxes(boxes, r, truth, tolerance);
      ra.samples = ra_error.samples;
      ra.erroneous = ra_error.erroneous;

      ComparisonRow pg = base;
      pg.method = "PG";
      pg.ms_per_frame = lane.pg_ms / n;
      if (!lane.state.map)
        throw Exception(
          "dataset " + ds.name
          + ": the pipeline has no map_integration stage (PG is its map)");
      const PlanarGridMap& map = *lane.state.map;
      const PlanarCuboids& cuboids = map.getSurfaceLayer().getCuboids();
      const double thres = map.getParams().surface.occupancy_thres;
      for (const auto& c : cuboids)
        pg.cells += c.probability >= thres;
      pg.all_cells = cuboids.size();
      pg.memory_bytes = map.getMemory().total_bytes;
      const MappingError pg_error =
        evaluateCuboids(cuboids, thres, r, truth, tolerance);
      pg.samples = pg_error.samples;
      pg.erroneous = pg_error.erroneous;
      PlanarCuboids planar;
      std::size_t planar_occupied = 0;
      for (const auto& c : cuboids)
        if (c.is_planar) {
          planar.push_back(c);
          planar_occupied += c.probability >= thres;
        }
      const MappingError planar_error =
        evaluateCuboids(planar, thres, r, truth, tolerance);
      pg.planar_samples = planar_error.samples;
      pg.planar_erroneous = planar_error.erroneous;

      for (ComparisonRow* row : {&sg, &og, &ra, &pg}) {
        row->efficiency =
          sg.cells > 0
            ? 1.0 - static_cast<double>(row->cells) / static_cast<double>(sg.cells)
            : 0.0;
        row->error = sg.cells > 0 ? static_cast<double>(row->erroneous)
                                      / static_cast<double>(sg.cells)
                                  : 0.0;
        rows.push_back(*row);
      }
      if (progress) {
        std::ostringstream line;
        line << std::fixed << std::setprecision(2) << ds.name << " @ " << r << " m, "
             << frames << " frames: cells SG " << sg.cells << ", OG " << og.cells
             << ", RA " << ra.cells << ", PG " << pg.cells << " (of " << pg.all_cells
             << "; planar " << planar.size() << ", occupied " << planar_occupied
             << "); error SG " << sg.error << ", PG " << pg.error << " (planar "
             << static_cast<double>(pg.planar_erroneous)
                  / static_cast<double>(std::max<std::size_t>(sg.cells, 1))
             << ")";
        progress(line.str());
      }
    }
  }
  return rows;
}

void
saveComparisonCsv(const std::vector<ComparisonRow>& rows, const std::string& path)
{
  std::ostringstream out;
  out << "dataset,environment,tilt_deg,resolution_m,method,frames,cells,all_cells,"
         "efficiency,memory_bytes,ms_per_frame,samples,erroneous,error,truth,"
         "planar_samples,planar_erroneous\n";
  out << std::setprecision(10);
  for (const auto& r : rows)
    out << r.dataset << "," << r.environment << "," << r.tilt_deg << ","
        << r.resolution_m << "," << r.method << "," << r.frames << "," << r.cells << ","
        << r.all_cells << "," << r.efficiency << "," << r.memory_bytes << ","
        << r.ms_per_frame << "," << r.samples << "," << r.erroneous << "," << r.error
        << "," << r.truth_kind << "," << r.planar_samples << "," << r.planar_erroneous
        << "\n";
  writeTextFileAtomically(path, out.str());
}

std::string
comparisonMarkdown(const std::vector<ComparisonRow>& rows)
{
  std::ostringstream out;
  out
    << "| dataset | cell m | method | cells | eta | memory kB | ms/frame | error e |\n"
       "|---|---|---|---|---|---|---|---|\n";
  out << std::fixed;
  for (const auto& r : rows)
    out << "| " << r.dataset << (r.truth_kind == "reference" ? " (ref.)" : "") << " | "
        << std::setprecision(1) << r.resolution_m << " | " << r.method << " | "
        << r.cells << " | " << std::setprecision(3) << r.efficiency << " | "
        << std::setprecision(1) << static_cast<double>(r.memory_bytes) / 1024.0 << " | "
        << std::setprecision(1) << r.ms_per_frame << " | " << std::setprecision(4)
        << r.error << " |\n";
  return out.str();
}

} // namespace planar_grid
