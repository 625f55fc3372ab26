// SPDX-License-Identifier: BSD-3-Clause
// planar_grid_eval: the paper's comparison (Sec. IV-B, Figs. 12-14) of a standard voxel
// grid (SG), OctoMap (OG), axis-aligned cuboids (RA) and the planar grid (PG) on the
// same frames at several minimum cell sizes; writes eval.csv, eval.md and the plots.
#include <planar_grid/core/atomic_file.h>
#include <planar_grid/core/exceptions.h>
#include <planar_grid/eval/map_comparison.h>
#include <planar_grid/eval/map_comparison_config.h>

#include "cli.h"
#ifdef PLANAR_GRID_WITH_VIEWER
#include <planar_grid/visualization/line_chart.h>
#include <planar_grid/visualization/scene_renderer.h>
#endif

#include <pcl/console/parse.h>
#include <pcl/console/print.h>

#include <algorithm>
#include <cstdlib>
#include <filesystem>
#include <iostream>
#include <map>
#include <set>
#include <string>
#include <vector>

using namespace pcl::console;

namespace {

void
printHelp(const char* program)
{
  print_info(
    "Syntax: %s --config EVAL.yaml [--output DIR] [--no-plots] [--save-maps]\n",
    program);
  print_info(
    "  Maps the datasets of EVAL.yaml (schema: config/eval_outdoor.yaml) with SG, "
    "OG, RA and PG\n  at each minimum cell size and writes eval.csv, eval.md "
    "and, unless --no-plots,\n  cells.png, efficiency.png, memory.png, error.png "
    "(and tilt.png for tilt-tagged datasets);\n  with places (the paper's Sec. "
    "IV-B) also places.csv and places_*.png, the means over the places;\n  with "
    "--save-maps (or output.save_maps) PG's maps, pg_DATASET_Rm.pgmap, SG's\n  "
    "occupied voxel centres, sg_DATASET_Rm.pcd, and the truth (or reference)\n  "
    "points, truth_DATASET.pcd.\n");
  print_info("  -h, --help  this help; --version  print the name and version\n");
}

#ifdef PLANAR_GRID_WITH_VIEWER
/** The mean of \a metric over the datasets, per method and cell size: one line per
 * method against the cell size (the paper's Figs. 12-14). */
void
savePlots(const std::vector<planar_grid::ComparisonRow>& rows,
          const planar_grid::ComparisonConfig& config,
          const std::string& folder,
          const std::string& prefix,
          const std::string& over,
          std::vector<std::string>& written)
{
  using Row = planar_grid::ComparisonRow;
  struct Metric {
    const char* file;
    const char* label;
    double (*value)(const Row&);
    bool log_y;
    bool skip_sg;
  };
  const std::vector<Metric> metrics{
    {"cells.png", "occupied cells",
     [](const Row& r) { return static_cast<double>(r.cells); }, true, false},
    {"efficiency.png", "combination efficiency eta = 1 - N / N_SG",
     [](const Row& r) { return r.efficiency; }, false, true},
    {"memory.png", "memory (kB)",
     [](const Row& r) { return static_cast<double>(r.memory_bytes) / 1024.0; }, true,
     false},
    {"error.png", "mapping error e = erroneous / N_SG",
     [](const Row& r) { return r.error; }, false, false},
  };
  const std::vector<std::string> methods{"SG", "OG", "RA", "PG"};
  std::set<std::string> datasets;
  for (const auto& r : rows)
    datasets.insert(r.dataset);
  for (const auto& m : metrics) {
    planar_grid::LineChart chart;
    chart.title = config.environment + ": " + m.label + ", mean of "
                  + std::to_string(datasets.size()) + " dataset(s)" + over;
    chart.x_label = "minimum cell size (m)";
    chart.y_label = m.label;
    chart.log_y = m.log_y;
    for (const auto& method : methods) {
      if (m.skip_sg && method == "SG")
        continue;
      planar_grid::LineSeries series;
      series.name = method;
      for (const double res : config.resolutions_m) {
        double sum = 0.0;
        int n = 0;
        for (const auto& r : rows)
          if (r.method == method && std::abs(r.resolution_m - res) < 1e-9) {
            sum += m.value(r);
            ++n;
          }
        if (n > 0) {
          series.x.push_back(res);
          series.y.push_back(sum / n);
        }
      }
      chart.series.push_back(series);
    }
    const std::string path =
      (std::filesystem::path(folder) / (prefix + m.file)).string();
    planar_grid::saveLineChart(chart, path);
    written.push_back(path);
  }
  // Cells against the tilt of the scene, at the smallest cell size.
  const double smallest =
    *std::min_element(config.resolutions_m.begin(), config.resolutions_m.end());
  planar_grid::LineChart tilt;
  tilt.title = config.environment
               + ": occupied cells against the surfaces' angle to the "
                 "map axes, cell size "
               + std::to_string(smallest).substr(0, 4) + " m";
  tilt.x_label = "tilt (deg)";
  tilt.y_label = "occupied cells";
  for (const auto& method : methods) {
    planar_grid::LineSeries series;
    series.name = method;
    std::map<double, double> by_tilt;
    for (const auto& r : rows)
      if (r.method == method && r.tilt_deg >= 0.0
          && std::abs(r.resolution_m - smallest) < 1e-9)
        by_tilt[r.tilt_deg] = static_cast<double>(r.cells);
    for (const auto& [t, cells] : by_tilt) {
      series.x.push_back(t);
      series.y.push_back(cells);
    }
    if (series.x.size() > 1)
      tilt.series.push_back(series);
  }
  if (!tilt.series.empty()) {
    const std::string path =
      (std::filesystem::path(folder) / (prefix + "tilt.png")).string();
    planar_grid::saveLineChart(tilt, path);
    written.push_back(path);
  }
}
#endif

int
run(int argc, char** argv)
{
  if (argc < 2 || find_switch(argc, argv, "-h") || find_switch(argc, argv, "--help")) {
    printHelp(argv[0]);
    return argc < 2 ? EXIT_FAILURE : EXIT_SUCCESS;
  }
  const std::vector<std::string> with_value{"--config", "--output"};
  const std::vector<std::string> switches{"--no-plots", "--save-maps", "-v"};
  planar_grid::cli::checkArguments(argc, argv, with_value, switches);
  if (find_switch(argc, argv, "-v"))
    setVerbosityLevel(L_DEBUG);
  else
    setVerbosityLevel(L_ERROR); // PCL's per-sample RANSAC warnings on sparse frames
  std::string config_path, output;
  if (parse_argument(argc, argv, "--config", config_path) < 0 || config_path.empty())
    throw planar_grid::Exception("--config EVAL.yaml is required (see --help)");
  planar_grid::ComparisonConfig config = planar_grid::loadComparisonConfig(config_path);
  if (parse_argument(argc, argv, "--output", output) >= 0)
    config.output_folder = output;
  const bool plots = !find_switch(argc, argv, "--no-plots");
  if (find_switch(argc, argv, "--save-maps"))
    config.save_maps = true;
#ifdef PLANAR_GRID_WITH_VIEWER
  if (plots)
    planar_grid::ensureDisplay(argc, argv); // VTK charts need an X server (Xvfb)
#else
  if (plots)
    print_warn("Built without the viewer (PLANAR_GRID_BUILD_VIEWER=OFF): no plots.\n");
#endif
  std::error_code ec;
  std::filesystem::create_directories(config.output_folder, ec);
  if (ec)
    throw planar_grid::IOError(config.output_folder
                               + ": cannot create the output folder: " + ec.message());

  std::cout << "Evaluation " << config_path << ": " << config.datasets.size()
            << " dataset(s), " << config.resolutions_m.size() << " cell sizes\n";
  const auto rows = planar_grid::runComparison(
    config, [](const std::string& line) { std::cout << "  " << line << std::endl; });

  std::vector<planar_grid::ComparisonRow> whole, places;
  for (const auto& row : rows)
    (row.place < 0 ? whole : places).push_back(row);
  std::vector<std::string> written;
  const std::string csv =
    (std::filesystem::path(config.output_folder) / "eval.csv").string();
  planar_grid::saveComparisonCsv(whole, csv);
  written.push_back(csv);
  if (!places.empty()) {
    const std::string places_csv =
      (std::filesystem::path(config.output_folder) / "places.csv").string();
    planar_grid::saveComparisonCsv(places, places_csv);
    written.push_back(places_csv);
  }
  const std::string table = planar_grid::comparisonMarkdown(rows);
  const std::string md =
    (std::filesystem::path(config.output_folder) / "eval.md").string();
  planar_grid::writeTextFileAtomically(md, table);
  written.push_back(md);
#ifdef PLANAR_GRID_WITH_VIEWER
  if (plots) {
    savePlots(whole, config, config.output_folder, "", "", written);
    if (!places.empty())
      savePlots(places, config, config.output_folder, "places_",
                " at " + std::to_string(config.places) + " places", written);
  }
#endif
  std::cout << "\n" << table << "\nOutputs:\n";
  for (const auto& path : written)
    std::cout << "  " << path << "\n";
  return EXIT_SUCCESS;
}

} // namespace

int
main(int argc, char** argv)
{
  return planar_grid::cli::runMain("planar_grid_eval", run, argc, argv);
}
