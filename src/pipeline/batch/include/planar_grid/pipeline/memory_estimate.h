// SPDX-License-Identifier: BSD-3-Clause
#pragma once

#include <planar_grid/odometry/trajectory_io.h>
#include <planar_grid/pipeline/pinhole_view.h>
#include <planar_grid/pipeline/pipeline_config.h>

#include <cstddef>
#include <cstdint>
#include <string>

namespace planar_grid {

/** \brief Volume of the points within \a margin_m of a pinhole view's frustum (the
 * pyramid of the image's pixel area, depth 0 to \a max_range_m), bounded from above by
 * the intersection of its six faces' half-spaces each moved out by \a margin_m. With
 * \a margin_m = 0 it is the pyramid's volume, max_range_m^3 / 3 times the image's
 * width and height over the focal lengths.
 * \param[in] view the camera (width, height, fx, fy > 0)
 * \param[in] max_range_m the largest depth, meters (> 0)
 * \param[in] margin_m the dilation, meters (>= 0)
 * \return cubic meters \ingroup pipeline */
double
pinholeFrustumVolume(const PinholeView& view, double max_range_m, double margin_m);

/** \brief An upper bound of the memory a run needs, from the cell size, the sensor's
 * range and field of view, and the frames (docs/RELIABILITY.md, "Memory"). Only the
 * map's explicit space layer grows as the cube of 1 / resolution_m; the rest of the
 * process (libraries, images, stereo buffers, clouds, the surface layer, the outputs)
 * is a fixed allowance, OTHER_BYTES. \ingroup pipeline */
struct MemoryEstimate {
  /** \brief The rest of the process, bytes: 512 MiB (the main job's peak with its
   * outputs and snapshots is below 0.5 GB, docs/RELIABILITY.md). */
  static constexpr std::uint64_t OTHER_BYTES = std::uint64_t{512} << 20;

  /** \brief True when the pipeline has a map_integration stage (otherwise only
   * other_bytes is counted). */
  bool has_map{false};
  /** \brief The map's voxel edge, meters. */
  double resolution_m{0.0};
  /** \brief The map's max_range_m, meters. */
  double max_range_m{0.0};
  /** \brief How a view was bounded: "pinhole WxH px" or "rays (ball of max_range_m)".
   */
  std::string sensor;
  /** \brief Frames of the run. */
  std::size_t frames{0};
  /** \brief Blocks (8^3 voxels) one view can touch, at most. */
  std::uint64_t view_blocks{0};
  /** \brief Blocks the map can store, at most. */
  std::uint64_t map_blocks{0};
  /** \brief Super-blocks (64^3 voxels) holding them, at most. */
  std::uint64_t map_super_blocks{0};
  /** \brief What bounds map_blocks: "frames" (frames times a view), "swept path" (the
   * union of the frames' views, from the poses known before the run) or "window"
   * (map_integration.window_radius_m). */
  std::string map_bound;
  /** \brief One view's working memory (ExplicitSpaceGrid::workingBytesBound()),
   * bytes. */
  std::uint64_t working_bytes{0};
  /** \brief The map's storage (ExplicitSpaceGrid::storageBytesBound()), bytes. */
  std::uint64_t map_bytes{0};
  /** \brief OTHER_BYTES. */
  std::uint64_t other_bytes{OTHER_BYTES};
  /** \brief working_bytes + map_bytes + other_bytes. */
  std::uint64_t total_bytes{OTHER_BYTES};

  /** \brief The key that sets the cell size, as the configuration names it
   * ("map_integration.resolution_m"), and where: file, 1-based line and column (0
   * when unknown). */
  std::string key;
  /** \brief The configuration file. */
  std::string file;
  /** \brief 1-based line of the key, 0 when unknown. */
  int line{0};
  /** \brief 1-based column of the key, 0 when unknown. */
  int column{0};

  /** \brief One line: the total and its terms. */
  std::string summary() const;
};

/** \brief Bounds the memory of a run of \a config.
 * \param[in] config the pipeline
 * \param[in] camera the stereo input's camera (nullptr for point clouds, or when not
 * known: a pinhole view is then bounded by the ball of max_range_m)
 * \param[in] poses world_T_camera of the frames of the run, in order (empty when not
 * known before the run, e.g. visual odometry): with them the map is bounded by the
 * union of the views
 * \param[in] frames frames of the run
 * \return the estimate \ingroup pipeline */
MemoryEstimate estimateRunMemory(const PipelineConfig& config,
                                 const PinholeView* camera,
                                 const Trajectory& poses,
                                 std::size_t frames);

/** \brief A memory limit and where it comes from. \ingroup pipeline */
struct MemoryLimit {
  /** \brief Bytes; 0 = no limit. */
  std::uint64_t bytes{0};
  /** \brief Where it comes from, for messages ("MemTotal of /proc/meminfo",
   * "RLIMIT_AS (ulimit -v)", "--memory-limit"). */
  std::string source;
};

/** \brief The default limit: the machine's physical memory (MemTotal of
 * /proc/meminfo, or sysconf's physical pages), or less where the process's address
 * space or data segment is limited (RLIMIT_AS, ulimit -v; RLIMIT_DATA, ulimit -d).
 * \ingroup pipeline */
MemoryLimit machineMemoryLimit();

/** \brief The smallest of the given limits, with its source; a value of 0 is no limit.
 * \param[in] physical_bytes the machine's memory, bytes
 * \param[in] address_space_bytes the soft RLIMIT_AS, bytes
 * \param[in] data_bytes the soft RLIMIT_DATA, bytes
 * \return machineMemoryLimit()'s rule applied to these values \ingroup pipeline */
MemoryLimit smallestMemoryLimit(std::uint64_t physical_bytes,
                                std::uint64_t address_space_bytes,
                                std::uint64_t data_bytes);

/** \brief Parses a size: bytes, or a number with a K, M, G or T suffix (powers of
 * 1024; "1.5G"), or "0" / "none" for no limit (0).
 * \throws planar_grid::Exception for anything else \ingroup pipeline */
std::uint64_t parseMemorySize(const std::string& text);

/** \brief "1.45 GiB", "512 MiB", "900 KiB" or "12 B". \ingroup pipeline */
std::string formatBytes(std::uint64_t bytes);

/** \brief Refuses a run whose estimate exceeds the limit (a limit of 0 refuses
 * nothing).
 * \throws planar_grid::ConfigError at the cell size's key, naming the estimate, the
 * limit and how to change either \ingroup pipeline */
void checkMemoryEstimate(const MemoryEstimate& estimate, const MemoryLimit& limit);

} // namespace planar_grid
