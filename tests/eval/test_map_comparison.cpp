// SPDX-License-Identifier: BSD-3-Clause
// The comparison driver of planar_grid_eval: its configuration is strict, and
// on a scene with known truth SG, OG, RA and PG give the figures an oracle predicts.
#include <planar_grid/core/exceptions.h>
#include <planar_grid/eval/map_comparison.h>
#include <planar_grid/eval/map_comparison_config.h>
#include <planar_grid/eval/standard_voxel_grid.h>
#include <planar_grid/map/planar_grid_map.h>
#include <planar_grid/pipeline/stage.h>

#include <pcl/filters/voxel_grid.h>
#include <pcl/io/pcd_io.h>
#include <pcl/point_types.h>

#include <gtest/gtest.h>
#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <iomanip>
#include <map>
#include <set>
#include <sstream>
#include <string>
#include <vector>

namespace fs = std::filesystem;

namespace {

class MapComparisonTest : public ::testing::Test {
protected:
  void SetUp() override
  {
    dir_ = fs::temp_directory_path()
           / ("planar_grid_map_comparison_" + std::to_string(::getpid()));
    fs::remove_all(dir_);
    fs::create_directories(dir_);
  }
  void TearDown() override { fs::remove_all(dir_); }

  std::string write(const std::string& name, const std::string& text) const
  {
    const std::string path = (dir_ / name).string();
    std::ofstream(path) << text;
    return path;
  }

  fs::path dir_;
};

/** A wall 4 m wide and 2 m high, 4 m in front of the origin, turned by \a yaw_rad
 * about z and leaning back by \a lean_rad (its normal is along no map axis), sampled
 * every \a step_m; a PCD frame seen from the origin (VIEWPOINT identity: the points
 * are in the world frame). */
pcl::PointCloud<pcl::PointXYZ>
wall(double yaw_rad, double lean_rad, double step_m)
{
  pcl::PointCloud<pcl::PointXYZ> cloud;
  const Eigen::Vector3d normal(std::cos(yaw_rad) * std::cos(lean_rad),
                               std::sin(yaw_rad) * std::cos(lean_rad),
                               std::sin(lean_rad));
  const Eigen::Vector3d along(-std::sin(yaw_rad), std::cos(yaw_rad), 0.0);
  const Eigen::Vector3d up = normal.cross(along);
  for (double s = -2.0; s <= 2.0 + 1e-9; s += step_m)
    for (double t = -1.0; t <= 1.0 + 1e-9; t += step_m) {
      const Eigen::Vector3d p = 4.0 * normal + s * along + t * up;
      cloud.push_back(pcl::PointXYZ(static_cast<float>(p.x()),
                                    static_cast<float>(p.y()),
                                    static_cast<float>(p.z())));
    }
  return cloud;
}

/** A pipeline of PCD frames \a files (comma-separated) through the planar stages: the
 * voxel grid at 0.1 m (set to r by the evaluation), segmentation of the cloud,
 * cuboids and the map. */
std::string
planarPipeline(const std::string& files, const std::string& poses = "")
{
  return "input:\n  type: pcd_files\n  files: [" + files + "]\n"
         + (poses.empty() ? std::string()
                          : "  poses: {format: kitti, file: " + poses + "}\n")
         + "pipeline:\n"
           "  - type: voxel_grid\n    params: {leaf_size_m: 0.1}\n"
           "  - type: transform_to_world\n"
           "  - type: multi_plane_segmentation\n"
           "    params: {sample: cloud, min_inliers: 100}\n"
           "  - type: planar_cuboid_approximation\n"
           "  - type: map_integration\n";
}

TEST_F(MapComparisonTest, ConfigurationErrorsNameTheLine)
{
  const std::string pipeline =
    write("p.yaml", "input:\n  type: pcd_files\n  files: [x.pcd]\n"
                    "pipeline:\n  - type: voxel_grid\n");
  const auto lineOf = [&](const std::string& yaml) {
    try {
      planar_grid::loadComparisonConfig(write("e.yaml", yaml));
    } catch (const planar_grid::ConfigError& e) {
      EXPECT_NE(std::string(e.what()).find("e.yaml"), std::string::npos) << e.what();
      return e.line();
    }
    ADD_FAILURE() << "no ConfigError for:\n" << yaml;
    return -1;
  };
  const std::string ds = "datasets:\n  - name: a\n    pipeline: " + pipeline
                         + "\n    truth: {type: reference}\n";
  EXPECT_EQ(lineOf("environment: indoors\n" + ds), 1);
  EXPECT_EQ(lineOf("resolutions_m: [0.1, -0.2]\n" + ds), 1);
  EXPECT_EQ(lineOf("resolution_m: [0.1]\n" + ds), 1); // unknown key
  EXPECT_EQ(lineOf(ds + "    frames: {step: 0}\n"), 5);
  EXPECT_EQ(lineOf("places: {count: 10, radius: 5.0}\n" + ds), 1); // unknown key
  EXPECT_EQ(lineOf("places: {count: -1}\n" + ds), 1);
  EXPECT_EQ(lineOf(ds + "output: {folder: o, save_maps: maybe}\n"), 5);
  EXPECT_EQ(lineOf("datasets:\n  - name: a\n    pipeline: " + pipeline
                   + "\n    truth: {type: exact}\n"),
            4);
  EXPECT_EQ(lineOf("datasets:\n  - name: a\n    pipeline: " + pipeline
                   + "\n    truth: {type: points, min_views: 2, file: t.pcd}\n"),
            4);
  // A dataset's parameter overrides: a list of STAGE.KEY=VALUE with known keys.
  EXPECT_EQ(lineOf(ds + "    set: voxel_grid.leaf_size_m=0.2\n"), 5);
  EXPECT_THROW(planar_grid::loadComparisonConfig(
                 write("s.yaml", ds + "    set: [voxel_grid.leaf_size=0.2]\n")),
               planar_grid::ConfigError);
  // The pipeline files' strict reading: a tab in the indentation, a syntax error.
  EXPECT_EQ(lineOf(ds + "\tplaces: {count: 1}\n"), 5);
  EXPECT_EQ(lineOf("environment: [indoor\n" + ds), 2);
  // A front-end stage after the cell-size stages cannot be shared by all sizes.
  const std::string late =
    write("late.yaml", "input:\n  type: pcd_files\n  files: [x.pcd]\n"
                       "pipeline:\n  - type: voxel_grid\n"
                       "  - type: feature_matching\n");
  EXPECT_THROW(planar_grid::loadComparisonConfig(
                 write("l.yaml", "datasets:\n  - name: a\n    pipeline: " + late
                                   + "\n    truth: {type: reference}\n")),
               planar_grid::ConfigError);
}

TEST_F(MapComparisonTest, TiltedWallAgainstItsTruth)
{
  // One frame of a wall turned 30 degrees and leaning 20 degrees, its own dense points
  // as truth.
  // The oracle: SG's occupied voxels equal a StandardVoxelGrid fed the same cloud; OG
  // equals SG (same sensor model); RA needs more boxes than a handful (the wall is not
  // axis-aligned) and fewer than SG; PG's planar cells are few (one plane) and on the
  // wall (no erroneous sample); every method's occupied cells lie on the truth.
  const auto cloud = wall(0.5236, 0.3491, 0.02);
  ASSERT_EQ(pcl::io::savePCDFileBinary((dir_ / "wall.pcd").string(), cloud), 0);
  ASSERT_EQ(pcl::io::savePCDFileBinary((dir_ / "truth.pcd").string(), cloud), 0);
  const std::string pipeline =
    write("p.yaml", planarPipeline((dir_ / "wall.pcd").string()));
  const auto config = planar_grid::loadComparisonConfig(
    write("e.yaml", "resolutions_m: [0.1, 0.2]\ndatasets:\n  - name: tilted wall\n"
                    "    pipeline: "
                      + pipeline + "\n    truth: {type: points, file: "
                      + (dir_ / "truth.pcd").string() + "}\n    tilt_deg: 30\n"
                      + "output: {folder: " + (dir_ / "maps").string()
                      + ", save_maps: true}\n"));
  ASSERT_TRUE(config.save_maps);
  const auto rows = planar_grid::runComparison(config, nullptr);
  ASSERT_EQ(rows.size(), 8u);
  std::map<std::pair<double, std::string>, planar_grid::ComparisonRow> by;
  for (const auto& r : rows)
    by[{r.resolution_m, r.method}] = r;

  for (const double r : {0.1, 0.2}) {
    // The oracle for SG: the voxelised cloud (what PG's approximation receives, here
    // the voxel_grid output at r) inserted from the PCD's viewpoint.
    const auto& sg = by.at({r, "SG"});
    const auto& og = by.at({r, "OG"});
    const auto& ra = by.at({r, "RA"});
    const auto& pg = by.at({r, "PG"});
    // The saved map is the one measured: its cuboids and occupied ones are PG's.
    EXPECT_EQ(planar_grid::mapComparisonFile("tilted wall", r),
              r < 0.15 ? "pg_tilted_wall_0.1m.pgmap" : "pg_tilted_wall_0.2m.pgmap");
    const auto saved = planar_grid::PlanarGridMap::load(
      (dir_ / "maps" / planar_grid::mapComparisonFile("tilted wall", r)).string());
    EXPECT_DOUBLE_EQ(saved.getParams().surface.resolution_m, r);
    const auto& saved_cuboids = saved.getSurfaceLayer().getCuboids();
    EXPECT_EQ(saved_cuboids.size(), pg.all_cells) << r;
    EXPECT_EQ(static_cast<std::size_t>(std::count_if(
                saved_cuboids.begin(), saved_cuboids.end(),
                [&saved](const planar_grid::PlanarCuboid& c) {
                  return c.probability >= saved.getParams().surface.occupancy_thres;
                })),
              pg.cells)
      << r;
    // SG's occupied voxels are saved beside it.
    EXPECT_EQ(planar_grid::sgComparisonFile("tilted wall", r),
              r < 0.15 ? "sg_tilted_wall_0.1m.pcd" : "sg_tilted_wall_0.2m.pcd");
    pcl::PointCloud<pcl::PointXYZ> sg_saved;
    ASSERT_EQ(
      pcl::io::loadPCDFile(
        (dir_ / "maps" / planar_grid::sgComparisonFile("tilted wall", r)).string(),
        sg_saved),
      0);
    EXPECT_EQ(sg_saved.size(), sg.cells) << r;
    pcl::PointCloud<pcl::PointXYZ>::Ptr input(
      new pcl::PointCloud<pcl::PointXYZ>(cloud));
    pcl::PointCloud<pcl::PointXYZ> voxelised;
    pcl::VoxelGrid<pcl::PointXYZ> grid;
    grid.setLeafSize(static_cast<float>(r), static_cast<float>(r),
                     static_cast<float>(r));
    grid.setInputCloud(input);
    grid.filter(voxelised);
    planar_grid::StandardVoxelGrid::Params params;
    params.resolution_m = r;
    planar_grid::StandardVoxelGrid oracle(params);
    oracle.insertPointCloud(voxelised, Eigen::Vector3f::Zero());
    EXPECT_EQ(sg.frames, 1u);
    EXPECT_GT(sg.cells, 0u);
    EXPECT_EQ(sg.cells, oracle.getOccupiedCount()) << r;
    EXPECT_EQ(sg.all_cells, oracle.getVoxelCount()) << r;
    EXPECT_EQ(og.cells, sg.cells) << r;
    EXPECT_DOUBLE_EQ(sg.efficiency, 0.0);
    EXPECT_GT(ra.cells, 5u) << r;
    EXPECT_LT(ra.cells, sg.cells) << r;
    EXPECT_GT(pg.cells, 0u);
    EXPECT_LT(pg.cells, ra.cells) << r;
    EXPECT_GT(pg.efficiency, ra.efficiency) << r;
    EXPECT_DOUBLE_EQ(pg.efficiency, 1.0 - static_cast<double>(pg.cells) / sg.cells);
    EXPECT_EQ(sg.erroneous, 0u) << r;
    EXPECT_EQ(pg.planar_erroneous, 0u) << r;
    // The own error is each method's erroneous samples over its own samples: 0 here.
    for (const auto* row : {&sg, &og, &ra, &pg}) {
      ASSERT_GT(row->samples, 0u) << row->method;
      EXPECT_DOUBLE_EQ(row->own_error, static_cast<double>(row->erroneous)
                                         / static_cast<double>(row->samples))
        << row->method;
    }
    // PG's planar cells lie on the wall, whose own points are the truth: their faces
    // see a surface of their orientation nearly everywhere (a face sample may reach
    // past the wall's edge into empty space).
    EXPECT_GT(pg.plane_area_m2, 0.0) << r;
    EXPECT_GT(pg.plane_precision, 0.9) << r;
    EXPECT_LE(pg.plane_precision, 1.0) << r;
    EXPECT_NEAR(pg.plane_precision + pg.plane_no_truth_share
                  + pg.plane_not_surface_share + pg.plane_misoriented_share,
                1.0, 1e-9)
      << r;
    for (const auto* row : {&sg, &og, &ra})
      EXPECT_TRUE(std::isnan(row->plane_precision)) << row->method;
    EXPECT_GT(pg.planar_samples, 0u);
    EXPECT_GT(pg.memory_bytes, 0u);
    EXPECT_GT(og.memory_bytes, 0u);
    EXPECT_DOUBLE_EQ(pg.tilt_deg, 30.0);
    EXPECT_EQ(pg.truth_kind, "truth");
    // Completeness: SG's occupied voxels are those of the truth's own points (each
    // input voxel's centroid lies in it), so it covers every truth voxel; OG and RA
    // hold SG's occupied voxels. PG's cuboids cover most of the wall, its planar ones
    // most of the wall above its lowest 0.3 m (the "ground" of a column without
    // floor).
    EXPECT_GT(sg.truth_voxels, 0u);
    for (const auto* row : {&og, &ra, &pg})
      EXPECT_EQ(row->truth_voxels, sg.truth_voxels) << row->method;
    EXPECT_EQ(sg.covered_voxels, sg.truth_voxels) << r;
    EXPECT_DOUBLE_EQ(sg.completeness, 1.0) << r;
    EXPECT_DOUBLE_EQ(og.completeness, 1.0) << r;
    EXPECT_DOUBLE_EQ(ra.completeness, 1.0) << r;
    EXPECT_GT(pg.completeness, 0.9) << r;
    EXPECT_LE(pg.completeness, 1.0) << r;
    EXPECT_GT(pg.nonground_voxels, 0u);
    EXPECT_LT(pg.nonground_voxels, pg.truth_voxels);
    EXPECT_GT(pg.planar_share, 0.9) << r;
    EXPECT_DOUBLE_EQ(pg.planar_share, static_cast<double>(pg.planar_covered_voxels)
                                        / static_cast<double>(pg.nonground_voxels));
    for (const auto* row : {&sg, &og, &ra})
      EXPECT_TRUE(std::isnan(row->planar_share)) << row->method;
    // Non-ground completeness: SG, OG and RA reach all of the truth above the ground
    // as they reach all of it; PG's planar cells reach no more than all its cells.
    for (const auto* row : {&sg, &og, &ra, &pg})
      EXPECT_EQ(row->nonground_voxels, pg.nonground_voxels) << row->method;
    for (const auto* row : {&sg, &og, &ra}) {
      EXPECT_EQ(row->nonground_covered_voxels, row->nonground_voxels) << row->method;
      EXPECT_DOUBLE_EQ(row->nonground_completeness, 1.0) << row->method;
    }
    EXPECT_GE(pg.nonground_covered_voxels, pg.planar_covered_voxels) << r;
    EXPECT_LE(pg.nonground_covered_voxels, pg.covered_voxels) << r;
    EXPECT_DOUBLE_EQ(pg.nonground_completeness,
                     static_cast<double>(pg.nonground_covered_voxels)
                       / static_cast<double>(pg.nonground_voxels));
    // The whole map: SG's, OG's and RA's are their cells; PG's adds the space layer's
    // occupied voxels to its cuboids, so it covers at least what the cuboids do, and
    // here, the space layer holding the wall's own voxels, all of it.
    for (const auto* row : {&sg, &og, &ra}) {
      EXPECT_EQ(row->map_covered_voxels, row->covered_voxels) << row->method;
      EXPECT_DOUBLE_EQ(row->map_completeness, row->completeness) << row->method;
    }
    EXPECT_GE(pg.map_covered_voxels, pg.covered_voxels) << r;
    EXPECT_EQ(pg.map_covered_voxels, pg.truth_voxels) << r;
    EXPECT_DOUBLE_EQ(pg.map_completeness, static_cast<double>(pg.map_covered_voxels)
                                            / static_cast<double>(pg.truth_voxels));
    // The mapped range: map_integration's max_range_m (25 m by default), the only
    // bound of this pipeline; a PCD frame has no image bounds, and the wall, 4 m in
    // front of the sensor, is all in range.
    for (const auto* row : {&sg, &og, &ra, &pg}) {
      EXPECT_DOUBLE_EQ(row->mapped_range_m, 25.0) << row->method;
      EXPECT_EQ(row->range_nonground_voxels, pg.nonground_voxels) << row->method;
    }
    EXPECT_EQ(sg.range_nonground_covered_voxels, sg.range_nonground_voxels) << r;
    EXPECT_LE(pg.range_planar_covered_voxels, pg.range_nonground_voxels) << r;
    EXPECT_DOUBLE_EQ(pg.range_planar_share,
                     static_cast<double>(pg.range_planar_covered_voxels)
                       / static_cast<double>(pg.range_nonground_voxels));
    for (const auto* row : {&sg, &og, &ra})
      EXPECT_TRUE(std::isnan(row->range_planar_share)) << row->method;
  }
  // A smaller cell size gives more SG cells.
  EXPECT_GT(by.at({0.1, "SG"}).cells, by.at({0.2, "SG"}).cells);

  const std::string csv = (dir_ / "eval.csv").string();
  planar_grid::saveComparisonCsv(rows, csv);
  std::ifstream in(csv);
  std::string header;
  std::getline(in, header);
  EXPECT_EQ(header.rfind("dataset,environment,tilt_deg,resolution_m,method", 0), 0u);
  // The completeness columns come after the earlier ones; the planar share and PG's
  // planar count are empty in the other methods' rows.
  const std::string tail = ",place,frame,region_radius_m,completeness,planar_share,"
                           "truth_voxels,covered_voxels,nonground_voxels,"
                           "planar_covered_voxels,nonground_completeness,"
                           "nonground_covered_voxels,map_completeness,"
                           "map_covered_voxels,mapped_range_m,range_nonground_voxels,"
                           "range_nonground_covered_voxels,"
                           "range_nonground_completeness,range_planar_covered_voxels,"
                           "range_planar_share,own_error,plane_precision,plane_area_m2,"
                           "plane_no_truth_share,plane_not_surface_share,"
                           "plane_misoriented_share";
  ASSERT_GE(header.size(), tail.size());
  EXPECT_EQ(header.substr(header.size() - tail.size()), tail);
  int lines = 0;
  for (std::string line; std::getline(in, line);) {
    ++lines;
    std::vector<std::string> fields;
    std::istringstream split(line);
    for (std::string field; std::getline(split, field, ',');)
      fields.push_back(field);
    if (line.back() == ',')
      fields.emplace_back();
    ASSERT_EQ(fields.size(), 42u) << line;
    const bool pg = fields[4] == "PG";
    if (pg) {
      EXPECT_FALSE(fields[20].empty()) << line;
      EXPECT_FALSE(fields[26].empty()) << line;
    } else {
      EXPECT_EQ(fields[20], "1") << line; // SG, OG and RA cover every truth voxel
      EXPECT_EQ(fields[26], "1") << line; // and every non-ground one
      EXPECT_EQ(fields[27], fields[24]) << line;
      EXPECT_EQ(fields[28], "1") << line; // their whole map is their cells
      EXPECT_EQ(fields[29], fields[23]) << line;
    }
    EXPECT_EQ(fields[30], "25") << line;
    EXPECT_EQ(fields[34].empty(), !pg) << line;
    EXPECT_EQ(fields[35].empty(), !pg) << line;
    EXPECT_EQ(fields[21].empty(), !pg) << line;
    EXPECT_FALSE(fields[24].empty()) << line;
    EXPECT_EQ(fields[25].empty(), !pg) << line;
    // The own error is the row's erroneous / samples (0: every method's cells lie on
    // the wall); the plane precision and face area are PG's alone.
    EXPECT_EQ(fields[36], "0") << line;
    EXPECT_EQ(fields[37].empty(), !pg) << line;
    EXPECT_EQ(fields[38].empty(), !pg) << line;
    // PG's imprecise face area by cause: the shares sum to 1 - plane_precision.
    for (int f = 39; f < 42; ++f)
      EXPECT_EQ(fields[static_cast<std::size_t>(f)].empty(), !pg) << line;
    if (pg) {
      EXPECT_NEAR(std::stod(fields[37]) + std::stod(fields[39]) + std::stod(fields[40])
                    + std::stod(fields[41]),
                  1.0, 1e-6)
        << line;
    }
  }
  EXPECT_EQ(lines, 8);
  const std::string md = planar_grid::comparisonMarkdown(rows);
  EXPECT_NE(md.find("| tilted wall | 0.1 | PG |"), std::string::npos);
  EXPECT_NE(
    md.find("| error e | own error | completeness | whole-map completeness | "
            "non-ground completeness | planar share | mapped range m | planar share in "
            "range | plane precision |"),
    std::string::npos);
  EXPECT_NE(md.find("| 0.0000 | 0.000 | 1.000 | 1.000 | 1.000 | - | 25.0 | - | - |"),
            std::string::npos)
    << md; // SG's row
}

TEST_F(MapComparisonTest, PlacesMeasureTheMapNearTheCameraAsTheFramesRun)
{
  // Two frames seen from the origin: a wall 4 m ahead (+x), then a wall 20 m to the
  // side (+y, its rays miss the first wall). Places: 5 asked for, 2 frames, so one
  // place after each frame, radius 8 m around the camera.
  // The oracle: a StandardVoxelGrid fed each frame's voxelised cloud in order. At both
  // places only the first wall is within 8 m, so both places count its SG cells; the
  // whole map at the end counts both walls; all_cells and memory are the whole map's.
  const auto near_wall = wall(0.0, 0.0, 0.02);
  auto far_wall = wall(1.5708, 0.0, 0.02);
  for (auto& p : far_wall.points)
    p.y += 16.0f; // 4 m -> 20 m from the origin
  // Both frames are taken at the origin, so they carry their pose in a KITTI file
  // (identical VIEWPOINTs would be refused as unregistered): the identity camera pose,
  // which the reader turns into the z-up world; the files hold the points in that
  // camera's optical frame (x right, y down, z forward), so that the world sees them
  // where the truth has them.
  const auto optical = [](const pcl::PointCloud<pcl::PointXYZ>& world) {
    pcl::PointCloud<pcl::PointXYZ> camera;
    for (const auto& p : world.points)
      camera.push_back(pcl::PointXYZ(-p.y, -p.z, p.x));
    return camera;
  };
  ASSERT_EQ(
    pcl::io::savePCDFileBinary((dir_ / "near.pcd").string(), optical(near_wall)), 0);
  ASSERT_EQ(pcl::io::savePCDFileBinary((dir_ / "far.pcd").string(), optical(far_wall)),
            0);
  write("poses.txt", "1 0 0 0 0 1 0 0 0 0 1 0\n1 0 0 0 0 1 0 0 0 0 1 0\n");
  pcl::PointCloud<pcl::PointXYZ> both = near_wall;
  both += far_wall;
  ASSERT_EQ(pcl::io::savePCDFileBinary((dir_ / "truth.pcd").string(), both), 0);
  const std::string pipeline =
    write("p.yaml", planarPipeline((dir_ / "near.pcd").string() + ", "
                                     + (dir_ / "far.pcd").string(),
                                   (dir_ / "poses.txt").string()));
  const auto config = planar_grid::loadComparisonConfig(
    write("e.yaml", "resolutions_m: [0.2]\nplaces: {count: 5, radius_m: 8.0}\n"
                    "datasets:\n  - name: walls\n    pipeline: "
                      + pipeline + "\n    truth: {type: points, file: "
                      + (dir_ / "truth.pcd").string() + "}\n"));
  EXPECT_EQ(config.places, 5u);
  EXPECT_DOUBLE_EQ(config.place_radius_m, 8.0);
  const auto rows = planar_grid::runComparison(config, nullptr);
  ASSERT_EQ(rows.size(), 12u); // 2 places x 4 methods, then the whole map x 4
  std::map<std::pair<int, std::string>, planar_grid::ComparisonRow> by;
  for (const auto& r : rows)
    by[{r.place, r.method}] = r;
  ASSERT_EQ(by.size(), 12u);

  const auto voxelised = [](const pcl::PointCloud<pcl::PointXYZ>& cloud) {
    pcl::PointCloud<pcl::PointXYZ>::Ptr input(
      new pcl::PointCloud<pcl::PointXYZ>(cloud));
    pcl::PointCloud<pcl::PointXYZ> out;
    pcl::VoxelGrid<pcl::PointXYZ> grid;
    grid.setLeafSize(0.2f, 0.2f, 0.2f);
    grid.setInputCloud(input);
    grid.filter(out);
    return out;
  };
  planar_grid::StandardVoxelGrid::Params params;
  params.resolution_m = 0.2;
  planar_grid::StandardVoxelGrid oracle(params);
  // The pipeline voxelises each frame in its camera's frame, then moves it to the
  // world.
  const auto world = [](const pcl::PointCloud<pcl::PointXYZ>& camera) {
    pcl::PointCloud<pcl::PointXYZ> out;
    for (const auto& p : camera.points)
      out.push_back(pcl::PointXYZ(p.z, -p.x, -p.y));
    return out;
  };
  oracle.insertPointCloud(world(voxelised(optical(near_wall))),
                          Eigen::Vector3f::Zero());
  const std::size_t near_cells = oracle.getOccupiedCount();
  const std::size_t after_first = oracle.getVoxelCount();
  oracle.insertPointCloud(world(voxelised(optical(far_wall))), Eigen::Vector3f::Zero());
  ASSERT_GT(oracle.getOccupiedCount(), near_cells + 50);

  const auto& sg0 = by.at({0, "SG"});
  const auto& sg1 = by.at({1, "SG"});
  const auto& sg = by.at({-1, "SG"});
  EXPECT_EQ(sg0.frame, 0u);
  EXPECT_EQ(sg0.frames, 1u);
  EXPECT_EQ(sg1.frame, 1u);
  EXPECT_EQ(sg1.frames, 2u);
  EXPECT_DOUBLE_EQ(sg0.region_radius_m, 8.0);
  EXPECT_EQ(sg0.cells, near_cells);
  EXPECT_EQ(sg0.all_cells, after_first);
  EXPECT_EQ(sg1.cells, near_cells);
  EXPECT_EQ(sg1.all_cells, oracle.getVoxelCount());
  EXPECT_EQ(sg.cells, oracle.getOccupiedCount());
  EXPECT_EQ(sg.place, -1);
  EXPECT_EQ(sg.frames, 2u);
  EXPECT_GT(sg1.memory_bytes, sg0.memory_bytes);
  EXPECT_EQ(sg1.memory_bytes, sg.memory_bytes);
  // OG equals SG at the places too; PG and RA count fewer cells near the camera at the
  // second place than in the whole map, and PG's planar cells are on the truth.
  EXPECT_EQ(by.at({0, "OG"}).cells, near_cells);
  EXPECT_EQ(by.at({1, "OG"}).cells, near_cells);
  for (const std::string method : {"RA", "PG"}) {
    EXPECT_GT(by.at({1, method}).cells, 0u) << method;
    EXPECT_LT(by.at({1, method}).cells, by.at({-1, method}).cells) << method;
    EXPECT_EQ(by.at({0, method}).cells, by.at({1, method}).cells) << method;
  }
  // Completeness at the places counts the truth voxels near the camera (the near
  // wall's), in the whole map all of them (both walls, about twice as many); SG
  // covers every one.
  EXPECT_GT(by.at({0, "SG"}).truth_voxels, 0u);
  EXPECT_EQ(by.at({0, "SG"}).truth_voxels, by.at({1, "SG"}).truth_voxels);
  EXPECT_GT(by.at({-1, "SG"}).truth_voxels, 3 * by.at({1, "SG"}).truth_voxels / 2);
  for (int place : {0, 1, -1}) {
    EXPECT_DOUBLE_EQ(by.at({place, "SG"}).completeness, 1.0) << place;
    EXPECT_GT(by.at({place, "PG"}).completeness, 0.5) << place;
    EXPECT_GT(by.at({place, "PG"}).planar_share, 0.5) << place;
    // PG's whole map: its space layer holds the voxel of every measured point, as SG
    // does, so it covers every truth voxel too, more than its cuboids alone.
    EXPECT_EQ(by.at({place, "PG"}).map_covered_voxels,
              by.at({place, "SG"}).covered_voxels)
      << place;
    EXPECT_LT(by.at({place, "PG"}).covered_voxels,
              by.at({place, "PG"}).map_covered_voxels)
      << place;
    EXPECT_TRUE(std::isnan(by.at({place, "RA"}).planar_share)) << place;
    EXPECT_GT(by.at({place, "PG"}).plane_precision, 0.9) << place;
    EXPECT_TRUE(std::isnan(by.at({place, "SG"}).plane_precision)) << place;
    EXPECT_EQ(by.at({place, "SG"}).erroneous, 0u) << place;
    EXPECT_EQ(by.at({place, "PG"}).planar_erroneous, 0u) << place;
    EXPECT_DOUBLE_EQ(by.at({place, "PG"}).efficiency,
                     1.0
                       - static_cast<double>(by.at({place, "PG"}).cells)
                           / static_cast<double>(by.at({place, "SG"}).cells));
  }
  const std::string md = planar_grid::comparisonMarkdown(rows);
  EXPECT_NE(md.find("| walls | 2 | 8.0 | 0.2 | PG |"), std::string::npos) << md;
  // The place means end with the completeness, the whole-map completeness, the
  // non-ground completeness, the planar share, the planar share in the mapped range
  // and the plane precision ("-" for SG); PG's non-ground mean is that of its two
  // places.
  const auto lineOf = [&md](const std::string& start) {
    const std::size_t at = md.find(start);
    return at == std::string::npos ? std::string()
                                   : md.substr(at, md.find('\n', at) - at);
  };
  const std::string sg_line = lineOf("| walls | 2 | 8.0 | 0.2 | SG |");
  ASSERT_FALSE(sg_line.empty()) << md;
  EXPECT_EQ(sg_line.substr(sg_line.size() - 37),
            "| 1.000 | 1.000 | 1.000 | - | - | - |")
    << sg_line;
  const std::string pg_line = lineOf("| walls | 2 | 8.0 | 0.2 | PG |");
  ASSERT_FALSE(pg_line.empty()) << md;
  std::ostringstream pg_nonground;
  pg_nonground << std::fixed << std::setprecision(3)
               << 0.5
                    * (by.at({0, "PG"}).nonground_completeness
                       + by.at({1, "PG"}).nonground_completeness);
  std::vector<std::string> pg_fields;
  std::istringstream pg_split(pg_line);
  for (std::string field; std::getline(pg_split, field, '|');)
    pg_fields.push_back(field);
  ASSERT_EQ(pg_fields.size(), 18u) << pg_line; // empty first field, 17 columns
  EXPECT_EQ(pg_fields[14], " " + pg_nonground.str() + " ") << pg_line;

  // A dataset's own places override the top level's: radius 0 is the whole map, so the
  // last place is the whole map after the last frame.
  const auto whole = planar_grid::loadComparisonConfig(
    write("w.yaml", "resolutions_m: [0.2]\nplaces: {count: 5, radius_m: 8.0}\n"
                    "datasets:\n  - name: walls\n    pipeline: "
                      + pipeline
                      + "\n    places: {radius_m: 0}\n    truth: {type: points, file: "
                      + (dir_ / "truth.pcd").string() + "}\n"));
  ASSERT_EQ(whole.datasets.size(), 1u);
  EXPECT_EQ(whole.datasets[0].places, 5u);
  EXPECT_DOUBLE_EQ(whole.datasets[0].place_radius_m, 0.0);
  std::map<std::pair<int, std::string>, planar_grid::ComparisonRow> by_whole;
  for (const auto& r : planar_grid::runComparison(whole, nullptr))
    by_whole[{r.place, r.method}] = r;
  for (const std::string method : {"SG", "OG", "RA", "PG"}) {
    EXPECT_EQ(by_whole.at({1, method}).cells, by_whole.at({-1, method}).cells)
      << method;
    EXPECT_EQ(by_whole.at({1, method}).samples, by_whole.at({-1, method}).samples)
      << method;
  }
  EXPECT_EQ(by_whole.at({1, "SG"}).cells, oracle.getOccupiedCount());
}

TEST(StageTables, SayWhichParametersFollowTheCellSize)
{
  // The evaluation sets a stage's cell-size parameters to r from the stage's own table;
  // a size parameter left unmarked would silently stay at its configured value.
  using Scaling = planar_grid::ParamSpec::CellSizeScaling;
  const auto scalingOf = [](const std::string& type, const std::string& key) {
    const planar_grid::StageInfo* info = planar_grid::findStage(type);
    EXPECT_NE(info, nullptr) << type;
    for (const auto& spec : info->params)
      if (spec.key == key)
        return spec.cell_size_scaling;
    ADD_FAILURE() << type << " has no parameter " << key;
    return Scaling::NONE;
  };
  EXPECT_EQ(scalingOf("voxel_grid", "leaf_size_m"), Scaling::CELL_SIZE);
  EXPECT_EQ(scalingOf("map_integration", "resolution_m"), Scaling::CELL_SIZE);
  EXPECT_EQ(scalingOf("map_integration", "thickness_m"), Scaling::CELL_SIZE);
  EXPECT_EQ(scalingOf("map_integration", "max_range_m"), Scaling::NONE);
  for (const char* key :
       {"min_cell_size_m", "min_width_m", "min_height_m", "thickness_m"})
    EXPECT_EQ(scalingOf("planar_cuboid_approximation", key), Scaling::CELL_SIZE) << key;
  EXPECT_EQ(scalingOf("multi_plane_segmentation", "min_inliers"),
            Scaling::POINTS_PER_AREA);
  EXPECT_EQ(scalingOf("statistical_outlier_removal", "mean_k"), Scaling::NONE);
  // Every stage: a length parameter marked CELL_SIZE is in meters.
  for (const auto& info : planar_grid::stageRegistry())
    for (const auto& spec : info.params)
      if (spec.cell_size_scaling == Scaling::CELL_SIZE) {
        EXPECT_EQ(spec.unit, "m") << info.type << "." << spec.key;
      }
}

TEST(StageTables, DeclareTheFrontEndTheEvaluationRunsOncePerFrame)
{
  // The evaluation runs the front end once per frame and the rest once per cell size,
  // from the role each stage declares in the registry.
  using planar_grid::StageData;
  using planar_grid::StageRole;
  std::set<std::string> front_end;
  std::set<StageData> mapping_produces;
  for (const auto& info : planar_grid::stageRegistry())
    if (info.role == StageRole::FRONT_END)
      front_end.insert(info.type);
    else
      mapping_produces.insert(info.produces.begin(), info.produces.end());
  EXPECT_EQ(front_end,
            (std::set<std::string>{"stereo_disparity", "feature_matching",
                                   "kl_occupancy_filter", "visual_odometry"}));
  for (const auto& info : planar_grid::stageRegistry()) {
    if (info.role != StageRole::FRONT_END)
      continue;
    // Shared by every cell size: no parameter of a front-end stage may follow it ...
    for (const auto& spec : info.params)
      EXPECT_EQ(spec.cell_size_scaling, planar_grid::ParamSpec::CellSizeScaling::NONE)
        << info.type << "." << spec.key;
    // ... and it cannot need what only a per-size (mapping) stage gives.
    for (const StageData need : info.needs) {
      const bool from_front_end = std::any_of(
        planar_grid::stageRegistry().begin(), planar_grid::stageRegistry().end(),
        [need](const planar_grid::StageInfo& other) {
          return other.role == StageRole::FRONT_END
                 && std::count(other.produces.begin(), other.produces.end(), need) > 0;
        });
      const bool from_input = need == StageData::STEREO_IMAGES;
      EXPECT_TRUE(from_front_end || from_input || mapping_produces.count(need) == 0)
        << info.type << " needs " << planar_grid::stageDataName(need);
    }
  }
}

} // namespace

namespace {

TEST_F(MapComparisonTest, TheReferenceTakesThePointsWithinItsRange)
{
  // One frame of two walls seen from the origin, 4-4.6 m and 8-8.3 m away. A reference
  // of range 6 m holds the near wall alone: the same truth voxels as a reference of the
  // near wall's frame without a range, and fewer than both walls without one.
  auto near_wall = wall(0.0, 0.0, 0.02);
  auto both = near_wall;
  for (const auto& p : near_wall.points)
    both.push_back(pcl::PointXYZ(p.x + 4.0f, p.y, p.z));
  ASSERT_EQ(pcl::io::savePCDFileBinary((dir_ / "near.pcd").string(), near_wall), 0);
  ASSERT_EQ(pcl::io::savePCDFileBinary((dir_ / "both.pcd").string(), both), 0);
  const auto truthVoxels = [&](const std::string& frame, const std::string& range) {
    const std::string pipeline =
      write(frame + ".yaml", planarPipeline((dir_ / (frame + ".pcd")).string()));
    const auto config = planar_grid::loadComparisonConfig(
      write("e.yaml", "resolutions_m: [0.2]\ndatasets:\n  - name: walls\n"
                      "    pipeline: "
                        + pipeline + "\n    truth: {type: reference, min_views: 1"
                        + range + "}\n"));
    for (const auto& r : planar_grid::runComparison(config, nullptr))
      if (r.place < 0 && r.method == "SG")
        return r.truth_voxels;
    ADD_FAILURE() << "no SG row";
    return std::size_t{0};
  };
  const std::size_t near_alone = truthVoxels("near", "");
  EXPECT_GT(near_alone, 100u);
  EXPECT_EQ(truthVoxels("both", ", max_range_m: 6.0"), near_alone);
  EXPECT_GT(truthVoxels("both", ""), near_alone + 100);
  // The range belongs to the reference only, and is a distance.
  for (const std::string& truth :
       {std::string("{type: reference, max_range_m: 0}"),
        "{type: points, file: " + (dir_ / "near.pcd").string() + ", max_range_m: 5}"}) {
    try {
      planar_grid::loadComparisonConfig(write(
        "r.yaml", "datasets:\n  - name: a\n    pipeline: "
                    + (dir_ / "near.yaml").string() + "\n    truth: " + truth + "\n"));
      ADD_FAILURE() << "no ConfigError for truth " << truth;
    } catch (const planar_grid::ConfigError& e) {
      EXPECT_NE(std::string(e.what()).find("max_range_m"), std::string::npos)
        << e.what();
    }
  }
}

TEST_F(MapComparisonTest, TheReferenceHasEveryFrameWhenTheMethodsMapFewer)
{
  // Four Karlsruhe frames through stereo and the planar stages, dense on every frame
  // and on every second one: the reference (all frames' dense points) is the same
  // in both runs, while the methods get the points of half the frames.
  const std::string karlsruhe =
    std::string(PLANAR_GRID_DATA_DIR) + "/karlsruhe_2010_03_09_drive_0023";
  const std::string pipeline = write(
    "dense.yaml",
    "input:\n  type: stereo_sequence\n  left_images: " + karlsruhe
      + "/left/I1_%06d.png\n  right_images: " + karlsruhe
      + "/right/I2_%06d.png\n  first_index: 10\n  frame_count: 4\n"
      + "  calibration: {format: karlsruhe, file: " + karlsruhe + "/calib.txt}\n"
      + "  poses: {format: karlsruhe_insdata, file: " + karlsruhe
      + "/insdata.txt, camera_height_m: 1.57, camera_pitch_rad: 0.09}\n"
      + "pipeline:\n  - type: stereo_disparity\n"
      + "    params: {algorithm: sgbm_3way, max_range_m: 15.0}\n"
      + "  - type: voxel_grid\n    params: {leaf_size_m: 0.1}\n"
      + "  - type: transform_to_world\n" + "  - type: multi_plane_segmentation\n"
      + "    params: {sample: cloud, min_inliers: 300}\n"
      + "  - type: planar_cuboid_approximation\n" + "  - type: map_integration\n");
  // Fewer dense frames through the dataset's `set`, as --set would: every second
  // frame, or keyframes 2 m apart (frames 10-13 are about 1.3 m apart).
  const auto run = [&](const std::string& name, const std::string& set_list) {
    const std::string set =
      set_list.empty() ? std::string() : "    set: [" + set_list + "]\n";
    const auto config = planar_grid::loadComparisonConfig(write(
      name + ".yaml", "resolutions_m: [0.3]\ndatasets:\n  - name: k\n    pipeline: "
                        + pipeline + "\n" + set + "    truth: {type: reference}\n"));
    std::map<std::string, planar_grid::ComparisonRow> by;
    for (const auto& r : planar_grid::runComparison(config, nullptr))
      if (r.place < 0)
        by[r.method] = r;
    return by;
  };
  const auto every = run("every", "");
  ASSERT_EQ(every.count("SG"), 1u);
  EXPECT_GT(every.at("SG").truth_voxels, 1000u);
  for (const std::string& set :
       {std::string("stereo_disparity.every_n_frames=2"),
        std::string("stereo_disparity.frame_selection=keyframes, "
                    "stereo_disparity.keyframe_translation_m=2.0")}) {
    const auto fewer = run(set.size() < 40 ? "every_other" : "keyframes", set);
    ASSERT_EQ(fewer.count("SG"), 1u) << set;
    for (const auto& [method, row] : fewer)
      EXPECT_EQ(row.truth_voxels, every.at(method).truth_voxels)
        << method << ", " << set;
    EXPECT_LT(fewer.at("SG").cells, every.at("SG").cells) << set;
    EXPECT_GT(fewer.at("SG").cells, every.at("SG").cells / 3) << set;
  }
}

} // namespace
