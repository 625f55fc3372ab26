// SPDX-License-Identifier: BSD-3-Clause
// The results of the map comparison: the per-map file names, the CSV table and the
// Markdown report.
#include <planar_grid/core/atomic_file.h>
#include <planar_grid/eval/map_comparison.h>

#include <algorithm>
#include <cctype>
#include <cmath>
#include <iomanip>
#include <limits>
#include <sstream>
#include <vector>

namespace planar_grid {

namespace {

/** "PREFIX_DATASET_Rm.EXTENSION", characters other than letters, digits, '-', '_'
 * and '.' in the dataset's name replaced by '_'. */
std::string
comparisonFile(const char* prefix,
               const std::string& dataset,
               double resolution_m,
               const char* extension)
{
  std::string name = dataset;
  for (char& c : name)
    if (!std::isalnum(static_cast<unsigned char>(c)) && c != '-' && c != '_'
        && c != '.')
      c = '_';
  std::ostringstream file;
  file << prefix << "_" << name << "_" << resolution_m << "m." << extension;
  return file.str();
}

} // namespace

std::string
mapComparisonFile(const std::string& dataset, double resolution_m)
{
  return comparisonFile("pg", dataset, resolution_m, "pgmap");
}

std::string
sgComparisonFile(const std::string& dataset, double resolution_m)
{
  return comparisonFile("sg", dataset, resolution_m, "pcd");
}

void
saveComparisonCsv(const std::vector<ComparisonRow>& rows, const std::string& path)
{
  std::ostringstream out;
  out << "dataset,environment,tilt_deg,resolution_m,method,frames,cells,all_cells,"
         "efficiency,memory_bytes,ms_per_frame,samples,erroneous,error,truth,"
         "planar_samples,planar_erroneous,place,frame,region_radius_m,completeness,"
         "planar_share,truth_voxels,covered_voxels,nonground_voxels,"
         "planar_covered_voxels,nonground_completeness,nonground_covered_voxels,"
         "map_completeness,map_covered_voxels,mapped_range_m,range_nonground_voxels,"
         "range_nonground_covered_voxels,range_nonground_completeness,"
         "range_planar_covered_voxels,range_planar_share,own_error,plane_precision,"
         "plane_area_m2,plane_no_truth_share,plane_not_surface_share,"
         "plane_misoriented_share\n";
  out << std::setprecision(10);
  // NaN (no truth voxels or samples; the planar share and plane precision of SG, OG
  // and RA) is an empty field, as are PG's planar counts and face area in the other
  // methods' rows and an unbounded (infinite) mapped range.
  const auto ratio = [](double value) {
    std::ostringstream field;
    field << std::setprecision(10);
    if (std::isfinite(value))
      field << value;
    return field.str();
  };
  for (const auto& r : rows) {
    const bool pg = r.method == "PG";
    out << r.dataset << "," << r.environment << "," << r.tilt_deg << ","
        << r.resolution_m << "," << r.method << "," << r.frames << "," << r.cells << ","
        << r.all_cells << "," << r.efficiency << "," << r.memory_bytes << ","
        << r.ms_per_frame << "," << r.samples << "," << r.erroneous << "," << r.error
        << "," << r.truth_kind << "," << r.planar_samples << "," << r.planar_erroneous
        << "," << r.place << "," << r.frame << "," << r.region_radius_m << ","
        << ratio(r.completeness) << "," << ratio(r.planar_share) << ","
        << r.truth_voxels << "," << r.covered_voxels << "," << r.nonground_voxels << ","
        << (pg ? std::to_string(r.planar_covered_voxels) : std::string()) << ","
        << ratio(r.nonground_completeness) << "," << r.nonground_covered_voxels << ","
        << ratio(r.map_completeness) << "," << r.map_covered_voxels << ","
        << ratio(r.mapped_range_m) << "," << r.range_nonground_voxels << ","
        << r.range_nonground_covered_voxels << ","
        << ratio(r.range_nonground_completeness) << ","
        << (pg ? std::to_string(r.range_planar_covered_voxels) : std::string()) << ","
        << ratio(r.range_planar_share) << "," << ratio(r.own_error) << ","
        << ratio(r.plane_precision) << ","
        << (pg ? ratio(r.plane_area_m2) : std::string()) << ","
        << ratio(r.plane_no_truth_share) << "," << ratio(r.plane_not_surface_share)
        << "," << ratio(r.plane_misoriented_share) << "\n";
  }
  writeTextFileAtomically(path, out.str());
}

std::string
comparisonMarkdown(const std::vector<ComparisonRow>& rows)
{
  std::ostringstream out;
  // A ratio with 3 decimals, "-" where it is undefined (NaN).
  const auto ratio = [](double value) {
    std::ostringstream cell;
    if (std::isfinite(value))
      cell << std::fixed << std::setprecision(3) << value;
    else
      cell << "-";
    return cell.str();
  };
  // A depth with 1 decimal, "-" where it is unbounded.
  const auto range = [](double value) {
    std::ostringstream cell;
    if (std::isfinite(value))
      cell << std::fixed << std::setprecision(1) << value;
    else
      cell << "-";
    return cell.str();
  };
  // PG's completeness is its cuboids'; the whole-map completeness adds its space
  // layer's occupied voxels (SG's, OG's and RA's are their completeness). The own
  // error is each method's erroneous samples over its own samples; the plane
  // precision is PG's alone.
  out
    << "| dataset | cell m | method | cells | eta | memory kB | ms/frame | error e | "
       "own error | completeness | whole-map completeness | non-ground completeness | "
       "planar share | mapped range m | planar share in range | plane precision |\n"
       "|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|\n";
  out << std::fixed;
  for (const auto& r : rows) {
    if (r.place >= 0)
      continue;
    out << "| " << r.dataset << (r.truth_kind == "reference" ? " (ref.)" : "") << " | "
        << std::setprecision(1) << r.resolution_m << " | " << r.method << " | "
        << r.cells << " | " << std::setprecision(3) << r.efficiency << " | "
        << std::setprecision(1) << static_cast<double>(r.memory_bytes) / 1024.0 << " | "
        << std::setprecision(1) << r.ms_per_frame << " | " << std::setprecision(4)
        << r.error << " | " << ratio(r.own_error) << " | " << ratio(r.completeness)
        << " | " << ratio(r.map_completeness) << " | "
        << ratio(r.nonground_completeness) << " | " << ratio(r.planar_share) << " | "
        << range(r.mapped_range_m) << " | " << ratio(r.range_planar_share) << " | "
        << ratio(r.plane_precision) << " |\n";
  }
  // The places: means over each dataset's places (the paper's Figs. 12-14).
  /** The mean of the defined (finite) values added; NaN when there is none. */
  struct FiniteMean {
    double sum{0.0};
    std::size_t count{0};
    void add(double value)
    {
      if (std::isfinite(value)) {
        sum += value;
        ++count;
      }
    }
    double value() const
    {
      return count > 0 ? sum / static_cast<double>(count)
                       : std::numeric_limits<double>::quiet_NaN();
    }
  };
  struct Sum {
    std::size_t places{0};
    double cells{0.0}, efficiency{0.0}, memory_kb{0.0}, ms{0.0}, error{0.0};
    FiniteMean own_error, completeness, map_completeness, nonground_completeness,
      planar_share, range_planar_share, plane_precision;
    double radius_m{0.0};
    bool reference{false};
  };
  std::vector<std::pair<std::string, Sum>> sums;
  for (const auto& r : rows) {
    if (r.place < 0)
      continue;
    std::ostringstream key;
    key << r.dataset << "|" << std::setprecision(3) << r.resolution_m << "|"
        << r.method;
    auto it = std::find_if(sums.begin(), sums.end(),
                           [&key](const auto& kv) { return kv.first == key.str(); });
    if (it == sums.end()) {
      sums.emplace_back(key.str(), Sum{});
      it = std::prev(sums.end());
    }
    Sum& sum = it->second;
    ++sum.places;
    sum.cells += static_cast<double>(r.cells);
    sum.efficiency += r.efficiency;
    sum.memory_kb += static_cast<double>(r.memory_bytes) / 1024.0;
    sum.ms += r.ms_per_frame;
    sum.error += r.error;
    sum.own_error.add(r.own_error);
    sum.completeness.add(r.completeness);
    sum.map_completeness.add(r.map_completeness);
    sum.nonground_completeness.add(r.nonground_completeness);
    sum.planar_share.add(r.planar_share);
    sum.range_planar_share.add(r.range_planar_share);
    sum.plane_precision.add(r.plane_precision);
    sum.radius_m = r.region_radius_m;
    sum.reference = r.truth_kind == "reference";
  }
  if (sums.empty())
    return out.str();
  out << "\nMeans over the places (cells and error within the radius of the camera at "
         "each place; memory of the whole map then; ms of that frame; the own error "
         "over the places with samples, the completeness, whole-map completeness, "
         "non-ground completeness and planar shares over the places that have truth "
         "voxels within the radius, the plane precision over those with planar "
         "cells):\n\n"
         "| dataset | places | radius m | cell m | method | cells | eta | memory kB | "
         "ms/frame | error e | own error | completeness | whole-map completeness | "
         "non-ground completeness | planar share | planar share in range | plane "
         "precision |\n"
         "|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|\n";
  for (const auto& [key, sum] : sums) {
    std::vector<std::string> parts;
    std::istringstream split(key);
    for (std::string part; std::getline(split, part, '|');)
      parts.push_back(part);
    const auto n = static_cast<double>(sum.places);
    out << "| " << parts[0] << (sum.reference ? " (ref.)" : "") << " | " << sum.places
        << " | " << std::setprecision(1) << sum.radius_m << " | " << parts[1] << " | "
        << parts[2] << " | " << std::setprecision(0) << sum.cells / n << " | "
        << std::setprecision(3) << sum.efficiency / n << " | " << std::setprecision(1)
        << sum.memory_kb / n << " | " << sum.ms / n << " | " << std::setprecision(4)
        << sum.error / n << " | " << ratio(sum.own_error.value()) << " | "
        << ratio(sum.completeness.value()) << " | "
        << ratio(sum.map_completeness.value()) << " | "
        << ratio(sum.nonground_completeness.value()) << " | "
        << ratio(sum.planar_share.value()) << " | "
        << ratio(sum.range_planar_share.value()) << " | "
        << ratio(sum.plane_precision.value()) << " |\n";
  }
  return out.str();
}

} // namespace planar_grid
