// SPDX-License-Identifier: BSD-3-Clause
// Checkpoints of a pipeline run, so that a killed run loses no work: everything carried
// from one frame to the next in one file, written atomically, and the resume that reads
// it back.
#include <planar_grid/core/atomic_file.h>
#include <planar_grid/core/byte_io.h>
#include <planar_grid/core/exceptions.h>
#include <planar_grid/pipeline/pipeline_runner.h>

#include <pcl/console/print.h>

#include <signal.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <utility>
#include <vector>

#include "resume_data.h"

namespace planar_grid {

namespace {

/** Magic ("PGCK") and version of the checkpoint file. Version 2 adds the size and
 * content hash of the small files the run read at its start, version 3 those of the
 * frame files (images, clouds) of the frames before the checkpoint; older versions
 * are still read, without those checks. */
constexpr std::uint32_t CHECKPOINT_MAGIC = 0x4B434750u;
constexpr std::uint32_t CHECKPOINT_VERSION = 3;

/** The size in bytes and the 64-bit FNV-1a hash (offset basis 14695981039346656037,
 * prime 1099511628211) of the file \a path, read in blocks. \throws IOError naming
 * the file, as \a what, when it cannot be read. */
std::pair<std::uint64_t, std::uint64_t>
sizeAndHash(const std::string& path, const std::string& what)
{
  std::uint64_t size = 0, hash = 14695981039346656037ull;
  std::ifstream in(path, std::ios::binary);
  if (!in)
    throw IOError(path + ": cannot open " + what
                  + " to compare it with the checkpoint");
  std::vector<char> block(1 << 16);
  while (in) {
    in.read(block.data(), static_cast<std::streamsize>(block.size()));
    const auto n = static_cast<std::size_t>(in.gcount());
    for (std::size_t k = 0; k < n; ++k) {
      hash ^= static_cast<unsigned char>(block[k]);
      hash *= 1099511628211ull;
    }
    size += n;
  }
  if (in.bad())
    throw IOError(path + ": cannot read " + what
                  + " to compare it with the checkpoint");
  return {size, hash};
}

/** Coordinates beyond this are corrupt data, meters. */
constexpr float MAX_COORDINATE_M = 1e7f;

Eigen::Vector3f
getPoint(ByteReader& r)
{
  Eigen::Vector3f p;
  for (int k = 0; k < 3; ++k)
    p[k] = r.get<float>();
  // Accumulated clouds hold finite points only.
  if (!p.allFinite() || p.cwiseAbs().maxCoeff() > MAX_COORDINATE_M)
    r.fail("invalid point coordinates");
  return p;
}

void
putVector3(ByteWriter& w, const Eigen::Vector3f& v)
{
  for (int k = 0; k < 3; ++k)
    w.put(v[k]);
}

void
putCuboids(ByteWriter& w, const PlanarCuboids& cuboids)
{
  w.put(static_cast<std::uint64_t>(cuboids.size()));
  for (const auto& c : cuboids) {
    putVector3(w, c.centre);
    putVector3(w, c.normal);
    putVector3(w, c.horizontal_axis);
    w.put(c.width_m);
    w.put(c.height_m);
    w.put(c.thickness_m);
    w.put(static_cast<std::int32_t>(c.plane_id));
    w.put(static_cast<std::uint64_t>(c.point_count));
    w.put(static_cast<std::uint8_t>(c.is_planar));
    w.put(c.probability);
  }
}

void
getCuboids(ByteReader& r, PlanarCuboids& cuboids)
{
  constexpr std::size_t CUBOID_BYTES = 9 * 4 + 3 * 4 + 4 + 8 + 1 + 4;
  cuboids.resize(r.getCount(CUBOID_BYTES, "cuboid"));
  for (auto& c : cuboids) {
    c.centre = getPoint(r);
    c.normal = getPoint(r);
    c.horizontal_axis = getPoint(r);
    c.width_m = r.get<float>();
    c.height_m = r.get<float>();
    c.thickness_m = r.get<float>();
    c.plane_id = r.get<std::int32_t>();
    c.point_count = static_cast<std::size_t>(r.get<std::uint64_t>());
    c.is_planar = r.get<std::uint8_t>() != 0;
    c.probability = r.get<float>();
    if (!(c.width_m >= 0.0f && c.height_m >= 0.0f && c.thickness_m >= 0.0f
          && c.probability >= 0.0f && c.probability <= 1.0f))
      r.fail("invalid cuboid");
  }
}

/** Removes the temporary files writeFileAtomically() left beside \a path when a process
 * writing it was killed: ".<name>.tmp.<pid>" whose process no longer exists. */
void
removeStaleTemporaries(const std::string& path)
{
  namespace fs = std::filesystem;
  const fs::path target(path);
  const fs::path folder = target.has_parent_path() ? target.parent_path() : ".";
  const std::string prefix = "." + target.filename().string() + ".tmp.";
  std::error_code ec;
  for (const auto& entry : fs::directory_iterator(folder, ec)) {
    const std::string name = entry.path().filename().string();
    if (name.rfind(prefix, 0) != 0)
      continue;
    const std::string pid_text = name.substr(prefix.size());
    if (pid_text.empty()
        || pid_text.find_first_not_of("0123456789") != std::string::npos
        || pid_text.size() > 9)
      continue;
    const auto pid = static_cast<pid_t>(std::stol(pid_text));
    if (pid != ::getpid() && ::kill(pid, 0) != 0 && errno == ESRCH) {
      fs::remove(entry.path(), ec);
      PCL_WARN("[planar_grid::PipelineRunner] removed %s, left by a run that was "
               "killed while writing a checkpoint.\n",
               entry.path().c_str());
    }
  }
}

} // namespace

std::vector<PipelineRunner::InputStamp>
PipelineRunner::stampInputFiles(const PipelineConfig& config)
{
  std::vector<InputStamp> stamps;
  const auto stamp = [&stamps](const std::string& what, const std::string& path) {
    const auto [size, hash] = sizeAndHash(path, what);
    stamps.push_back({what, path, size, hash});
  };
  std::error_code ec;
  // A configuration parsed from text names its source without being a file.
  if (std::filesystem::is_regular_file(config.source_file, ec))
    stamp("the configuration file", config.source_file);
  const InputConfig& input = config.input;
  if (!input.calibration_file.empty())
    stamp("the calibration (input.calibration.file)", input.calibration_file);
  if (!input.calibration_right_file.empty())
    stamp("the right camera's calibration (input.calibration.right_file)",
          input.calibration_right_file);
  if (!input.poses_file.empty())
    stamp("the poses file (input.poses.file)", input.poses_file);
  return stamps;
}

std::string
PipelineRunner::fingerprint() const
{
  std::ostringstream out;
  out << "input " << source_->describe() << "\n";
  for (const auto& sc : config_.stages) {
    out << "stage " << sc.type;
    for (const auto& kv : sc.params.values())
      out << " " << kv.first << "=" << sc.params.toString(kv.first);
    out << "\n";
  }
  return out.str();
}

void
PipelineRunner::setCheckpoint(const std::string& path, std::size_t every_n_frames)
{
  if (every_n_frames > 0) {
    if (path.empty())
      throw ConfigError(config_.source_file, 0, 0,
                        "checkpoints need a file name (output.checkpoint)");
    for (std::size_t s = 0; s < mapper_->getStageCount(); ++s)
      if (!mapper_->getStage(s).supportsCheckpoint())
        throw ConfigError(config_.source_file, config_.stages[s].line,
                          config_.stages[s].column,
                          "stage '" + config_.stages[s].type
                            + "' cannot be checkpointed yet (its state across frames "
                              "is not written); run without checkpoints");
  }
  if (every_n_frames > 0) {
    const auto folder = std::filesystem::path(path).parent_path();
    std::error_code ec;
    if (!folder.empty())
      std::filesystem::create_directories(folder, ec);
    if (ec)
      throw OutputError(folder.string()
                        + ": cannot create the checkpoint folder: " + ec.message());
    removeStaleTemporaries(path);
    // Now, before the first frame: the content the run starts from.
    input_stamps_ = stampInputFiles(config_);
  }
  checkpoint_path_ = path;
  checkpoint_every_ = every_n_frames;
}

void
PipelineRunner::writeCheckpoint(std::size_t next_frame, const RunReport& report) const
{
  std::vector<std::uint8_t> bytes;
  ByteWriter w(bytes);
  w.put(CHECKPOINT_MAGIC);
  w.put(CHECKPOINT_VERSION);
  w.putString(fingerprint());
  w.put(static_cast<std::uint64_t>(input_stamps_.size()));
  for (const auto& stamp : input_stamps_) {
    w.putString(stamp.what);
    w.putString(stamp.path);
    w.put(stamp.size);
    w.put(stamp.hash);
  }
  w.put(static_cast<std::uint64_t>(begin_));
  w.put(static_cast<std::uint64_t>(next_frame));
  // The frames' own files, stamped once each: those read since the last checkpoint.
  for (std::size_t i = std::max(frame_stamps_until_, begin_); i < next_frame; ++i)
    for (const InputFile& file : source_->frameFiles(i)) {
      const std::string what = file.what + " of frame " + std::to_string(i);
      const auto [size, hash] = sizeAndHash(file.path, what);
      frame_stamps_.push_back({what, file.path, size, hash});
    }
  frame_stamps_until_ = std::max(frame_stamps_until_, next_frame);
  w.put(static_cast<std::uint64_t>(frame_stamps_.size()));
  for (const auto& stamp : frame_stamps_) {
    w.putString(stamp.what);
    w.putString(stamp.path);
    w.put(stamp.size);
    w.put(stamp.hash);
  }

  // The report so far, so that the resumed run reports the whole run.
  w.put(static_cast<std::uint64_t>(report.frames));
  w.put(report.load_ms);
  w.put(report.seconds);
  w.put(static_cast<std::uint64_t>(report.checkpoints_written));
  w.put(static_cast<std::uint64_t>(report.stages.size()));
  for (const auto& s : report.stages) {
    w.putString(s.type);
    w.put(static_cast<std::uint64_t>(s.frames));
    w.put(s.total_ms);
    w.put(s.max_ms);
    w.put(s.points_in);
    w.put(s.points_out);
    w.put(static_cast<std::uint64_t>(s.counters.size()));
    for (const auto& [name, value] : s.counters) {
      w.putString(name);
      w.put(value);
    }
  }
  w.put(static_cast<std::uint64_t>(report.rss_samples.size()));
  for (const auto& [frame, rss] : report.rss_samples) {
    w.put(static_cast<std::uint64_t>(frame));
    w.put(rss);
  }

  const Trajectory& trajectory = mapper_->getTrajectory();
  w.put(static_cast<std::uint64_t>(trajectory.size()));
  for (const auto& pose : trajectory)
    putPose(w, pose);

  // The shared state.
  const PipelineState& state = mapper_->getState();
  const auto& world = *state.world_cloud;
  w.put(static_cast<std::uint64_t>(world.size()));
  for (const auto& p : world.points) {
    putVector3(w, p.getVector3fMap());
    w.put(p.intensity);
  }
  const PlaneRegistry& planes = *state.planes;
  const auto& inliers = planes.getInlierCloud();
  w.put(static_cast<std::uint64_t>(inliers.size()));
  for (const auto& p : inliers.points) {
    putVector3(w, p.getVector3fMap());
    w.put(p.label);
  }
  w.put(static_cast<std::uint64_t>(planes.getModelCoefficients().size()));
  for (const auto& m : planes.getModelCoefficients())
    for (int k = 0; k < 4; ++k)
      w.put(m[k]);
  w.put(static_cast<std::uint64_t>(planes.getInlierCounts().size()));
  for (const auto n : planes.getInlierCounts())
    w.put(static_cast<std::uint64_t>(n));
  putCuboids(w, state.cuboids);
  w.put(static_cast<std::uint8_t>(state.map != nullptr));
  if (state.map) {
    std::string map_bytes;
    state.map->serialize(map_bytes);
    w.putString(map_bytes);
  }

  // Each stage's own state.
  const std::vector<std::vector<std::uint8_t>> stage_states =
    mapper_->saveStageStates();
  w.put(static_cast<std::uint64_t>(stage_states.size()));
  for (std::size_t s = 0; s < stage_states.size(); ++s) {
    w.putString(config_.stages[s].type);
    w.putVector(stage_states[s]);
  }
  w.put(crc32(bytes.data(), bytes.size()));

  writeFileAtomically(checkpoint_path_, [&bytes](const std::string& temporary) {
    std::ofstream out(temporary, std::ios::binary | std::ios::trunc);
    out.write(reinterpret_cast<const char*>(bytes.data()),
              static_cast<std::streamsize>(bytes.size()));
    out.close();
    return static_cast<bool>(out);
  });
}

namespace {

/** \brief The bytes of checkpoint \a path, its CRC-32 (the last 4 bytes) checked.
 * \throws IOError when it cannot be read, is truncated or its checksum differs. */
std::string
readCheckpointBytes(const std::string& path, const std::string& what)
{
  std::ifstream file(path, std::ios::binary);
  if (!file)
    throw IOError("checkpoint " + path + ": cannot be opened for reading");
  std::ostringstream content;
  content << file.rdbuf();
  std::string text = content.str();
  const auto* data = reinterpret_cast<const std::uint8_t*>(text.data());
  if (text.size() < 12)
    throw IOError(what + ": truncated (" + std::to_string(text.size()) + " bytes)");
  std::uint32_t stored_crc = 0;
  std::memcpy(&stored_crc, data + text.size() - 4, 4);
  if (crc32(data, text.size() - 4) != stored_crc)
    throw IOError(what + ": checksum mismatch: the file is corrupt or truncated");
  return text;
}

/** \brief Reads one stamp (what, path, size, hash) of a file. */
template <typename Stamp>
void
getStamp(ByteReader& r, const char* item, Stamp& stamp)
{
  stamp.what = r.getString(item);
  stamp.path = r.getString(item);
  stamp.size = r.get<std::uint64_t>();
  stamp.hash = r.get<std::uint64_t>();
}

/** \brief Reads the input files' stamps a checkpoint recorded and compares them with
 * \a now, this run's: a file read by one run and not the other, at another path or
 * with other bytes fails \a r. */
template <typename Stamp>
void
checkInputStamps(ByteReader& r, const std::vector<Stamp>& now)
{
  std::vector<Stamp> written(r.getCount(4 * 8, "input file"));
  for (auto& stamp : written)
    getStamp(r, "input file", stamp);
  const auto restart = ": resume with the files the checkpoint's run read, or start "
                       "a new run without --resume";
  for (const auto& stamp : now) {
    const auto it =
      std::find_if(written.begin(), written.end(),
                   [&stamp](const Stamp& w) { return w.what == stamp.what; });
    if (it == written.end())
      r.fail("written by a run that did not read " + stamp.what + ", and this run "
             + "reads " + stamp.path + restart);
    if (it->path != stamp.path)
      r.fail("written by a run whose " + stamp.what.substr(4) + " was " + it->path
             + ", and this run's is " + stamp.path + restart);
    if (it->size != stamp.size || it->hash != stamp.hash)
      r.fail(stamp.what + " " + stamp.path
             + " changed since the checkpoint was written (" + std::to_string(it->size)
             + " bytes then, " + std::to_string(stamp.size)
             + " bytes now; its content differs)" + restart);
  }
  for (const auto& stamp : written)
    if (std::none_of(now.begin(), now.end(),
                     [&stamp](const Stamp& n) { return n.what == stamp.what; }))
      r.fail("written by a run that read " + stamp.what + " " + stamp.path
             + ", which this run does not read" + restart);
}

/** \brief Reads the frame files' stamps (version 3) and checks each file against
 * its stamp: the map holds what these files held, and a file changed since would
 * leave the resumed map unlike a new run's. */
template <typename Stamp>
void
readFrameStamps(ByteReader& r, std::vector<Stamp>& stamps)
{
  stamps.resize(r.getCount(4 * 8, "frame file"));
  for (auto& stamp : stamps) {
    getStamp(r, "frame file", stamp);
    const auto [size, hash] = sizeAndHash(stamp.path, stamp.what);
    if (size != stamp.size || hash != stamp.hash)
      r.fail(stamp.what + " " + stamp.path
             + " changed since the checkpoint was written ("
             + std::to_string(stamp.size) + " bytes then, " + std::to_string(size)
             + " bytes now; its content differs): the map holds what it held; start "
               "a new run without --resume");
  }
}

/** \brief Reads the report up to the checkpoint: frames, times, checkpoints, each of
 * the \a stage_count stages' figures and counters, the memory samples. */
void
readRunReport(ByteReader& r, std::size_t stage_count, RunReport& report)
{
  report.frames = static_cast<std::size_t>(r.get<std::uint64_t>());
  report.load_ms = r.get<double>();
  report.seconds = r.get<double>();
  report.checkpoints_written = static_cast<std::size_t>(r.get<std::uint64_t>());
  if (r.getCount(8, "stage report") != stage_count)
    r.fail("stage count differs");
  for (std::size_t s = 0; s < stage_count; ++s) {
    StageReport sr;
    sr.type = r.getString("stage type");
    sr.frames = static_cast<std::size_t>(r.get<std::uint64_t>());
    sr.total_ms = r.get<double>();
    sr.max_ms = r.get<double>();
    sr.points_in = r.get<std::uint64_t>();
    sr.points_out = r.get<std::uint64_t>();
    const std::size_t counters = r.getCount(16, "counter");
    for (std::size_t c = 0; c < counters; ++c) {
      std::string name = r.getString("counter name");
      sr.counters.emplace_back(std::move(name), r.get<double>());
    }
    report.stages.push_back(std::move(sr));
  }
  const std::size_t samples = r.getCount(16, "memory sample");
  for (std::size_t k = 0; k < samples; ++k) {
    const auto frame = static_cast<std::size_t>(r.get<std::uint64_t>());
    report.rss_samples.emplace_back(frame, r.get<std::uint64_t>());
  }
}

/** \brief Reads the shared state: the world and plane clouds, the plane models and
 * their inlier counts, the cuboids and the map (decoded here, with every check of a
 * map file, so that a corrupt map is reported before the run starts). */
void
readSharedState(ByteReader& r, const std::string& path, PipelineState& state)
{
  const std::size_t world_points = r.getCount(16, "world cloud point");
  state.world_cloud->resize(world_points);
  for (auto& p : state.world_cloud->points) {
    p.getVector3fMap() = getPoint(r);
    p.intensity = r.get<float>();
  }
  const std::size_t plane_points = r.getCount(16, "plane cloud point");
  PlaneRegistry::PointCloud inliers;
  inliers.resize(plane_points);
  for (auto& p : inliers.points) {
    p.getVector3fMap() = getPoint(r);
    p.label = r.get<std::uint32_t>();
  }
  const std::size_t models = r.getCount(16, "plane model");
  PlaneRegistry::PlaneModels model_coefficients;
  model_coefficients.reserve(models);
  for (std::size_t k = 0; k < models; ++k) {
    Eigen::Vector4f m;
    for (int c = 0; c < 4; ++c)
      m[c] = r.get<float>();
    if (!m.allFinite())
      r.fail("non-finite plane model");
    model_coefficients.push_back(m);
  }
  const std::size_t counts = r.getCount(8, "plane inlier count");
  if (counts != models)
    r.fail("plane models and inlier counts of different lengths");
  std::vector<std::size_t> inlier_counts;
  inlier_counts.reserve(counts);
  for (std::size_t k = 0; k < counts; ++k)
    inlier_counts.push_back(static_cast<std::size_t>(r.get<std::uint64_t>()));
  for (const auto& p : inliers.points)
    if (p.label >= models)
      r.fail("plane cloud label " + std::to_string(p.label) + " beyond the "
             + std::to_string(models) + " plane models");
  state.planes->setPlanes(std::move(model_coefficients), std::move(inlier_counts),
                          std::move(inliers));
  getCuboids(r, state.cuboids);
  if (r.get<std::uint8_t>() != 0)
    state.map = std::make_shared<PlanarGridMap>(
      PlanarGridMap::deserialize(r.getString("map"), path + " (embedded map)"));
}

} // namespace

std::size_t
PipelineRunner::resumeFrom(const std::string& path)
{
  input("resumeFrom()");
  const std::string what = "checkpoint " + path;
  const std::string text = readCheckpointBytes(path, what);
  ByteReader r(reinterpret_cast<const std::uint8_t*>(text.data()), text.size() - 4,
               what);
  if (r.get<std::uint32_t>() != CHECKPOINT_MAGIC)
    r.fail("not a planar_grid_pipeline checkpoint");
  const auto version = r.get<std::uint32_t>();
  if (version < 1 || version > CHECKPOINT_VERSION)
    r.fail("version " + std::to_string(version)
           + " is not supported (this reader knows 1 to "
           + std::to_string(CHECKPOINT_VERSION) + ")");
  const std::string written_fingerprint = r.getString("fingerprint");
  // The files first: a changed calibration also changes the fingerprint, and the
  // message should name the file.
  if (version >= 2)
    checkInputStamps(r, stampInputFiles(config_));
  else
    PCL_WARN("[planar_grid::PipelineRunner::resumeFrom] %s: a version 1 checkpoint, "
             "which does not record its input files: a calibration, poses or "
             "configuration file changed since is not found.\n",
             path.c_str());
  if (written_fingerprint != fingerprint())
    r.fail("written by a different pipeline (its stages, parameters or input differ "
           "from this configuration's); resume with the configuration that wrote it");

  auto resume = std::make_unique<ResumeData>();
  resume->first_frame = static_cast<std::size_t>(r.get<std::uint64_t>());
  resume->next_frame = static_cast<std::size_t>(r.get<std::uint64_t>());
  if (resume->next_frame <= resume->first_frame || resume->next_frame > source_->size())
    r.fail("frame positions " + std::to_string(resume->first_frame) + ".."
           + std::to_string(resume->next_frame) + " do not fit the input's "
           + std::to_string(source_->size()) + " frames");
  if (version >= 3)
    readFrameStamps(r, resume->frame_stamps);
  readRunReport(r, mapper_->getStageCount(), resume->report);
  const std::size_t poses = r.getCount(12 * 8, "pose");
  for (std::size_t k = 0; k < poses; ++k)
    resume->trajectory.push_back(getPose(r));
  readSharedState(r, path, resume->state);

  const std::size_t stage_states = r.getCount(16, "stage state");
  if (stage_states != mapper_->getStageCount())
    r.fail("stage count differs");
  for (std::size_t s = 0; s < stage_states; ++s) {
    if (r.getString("stage type") != config_.stages[s].type)
      r.fail("stage " + std::to_string(s) + " differs");
    std::vector<std::uint8_t> bytes;
    r.getVector(bytes, "stage state");
    resume->stage_states.push_back(std::move(bytes));
  }
  if (r.remaining() != 0)
    r.fail(std::to_string(r.remaining()) + " bytes of trailing data");

  // The restored map holds the frames from the checkpoint's first one: a run over
  // another range would report one range and map another.
  if (resume->first_frame != begin_)
    throw IOError(what + ": written by a run that started at frame position "
                  + std::to_string(resume->first_frame)
                  + ", but this run's range starts at " + std::to_string(begin_)
                  + ": resume with the range it was written with (--frames "
                  + std::to_string(resume->first_frame)
                  + ":END), or start a new run without --resume");
  if (end_ <= resume->next_frame)
    throw IOError(what + ": the checkpoint is after frame position "
                  + std::to_string(resume->next_frame - 1)
                  + ", at or past the end of the range (" + std::to_string(end_)
                  + "): nothing left to run");
  const std::size_t next = resume->next_frame;
  resume_ = std::move(resume);
  return next;
}

} // namespace planar_grid
