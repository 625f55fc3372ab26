// SPDX-License-Identifier: BSD-3-Clause
// The surface layer's non-planar cells (Fig. 7): keys, the orientation table, and the
// replacement of the cells a newer frame overlaps.
#include <planar_grid/core/exceptions.h>
#include <planar_grid/map/surface_layer.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <mutex>
#include <set>
#include <tuple>
#include <unordered_map>
#include <utility>

#include "surface_layer_impl.h"

namespace planar_grid {

namespace surface_layer_detail {

NonPlanarKey
nonPlanarKey(const PlanarCuboid& c, double resolution_m)
{
  const double inv = 1.0 / resolution_m;
  const auto q = [](double x) {
    return static_cast<std::int32_t>(std::max(-2.0e9, std::min(2.0e9, std::floor(x))));
  };
  const auto r = [](double x) {
    return static_cast<std::int32_t>(std::max(-2.0e9, std::min(2.0e9, std::round(x))));
  };
  return NonPlanarKey{{q(c.centre.x() * inv), q(c.centre.y() * inv),
                       q(c.centre.z() * inv), r(c.width_m * inv), r(c.height_m * inv),
                       r(c.thickness_m * inv)}};
}

} // namespace surface_layer_detail

using namespace surface_layer_detail;

namespace {

/** A non-planar cell's extent in its own axes: (horizontal, vertical, normal)
 * coordinates, meters; \a axes its index into the orientation table. */
struct Span {
  std::uint32_t cell;
  std::uint32_t axes;
  Eigen::Vector3f lo;
  Eigen::Vector3f hi;
};

/** The axis along which the spans' starts spread the most, in units of their mean
 * extent plus \a slack: a sweep's window on it holds the fewest other spans (the depth
 * of a street, the length of a corridor). */
int
sweepAxis(const std::vector<Span>& spans, float slack)
{
  Eigen::Vector3f lo = Eigen::Vector3f::Constant(std::numeric_limits<float>::max());
  Eigen::Vector3f hi = Eigen::Vector3f::Constant(std::numeric_limits<float>::lowest());
  Eigen::Vector3d extent = Eigen::Vector3d::Zero();
  for (const Span& span : spans) {
    lo = lo.cwiseMin(span.lo);
    hi = hi.cwiseMax(span.lo);
    extent += (span.hi - span.lo).cast<double>();
  }
  int best = 0;
  double best_spread = -1.0;
  for (int a = 0; a < 3; ++a) {
    const double window = extent[a] / static_cast<double>(spans.size()) + slack;
    const double spread = static_cast<double>(hi[a] - lo[a]) / window;
    if (spread > best_spread) {
      best_spread = spread;
      best = a;
    }
  }
  return best;
}

/** Calls \a add(a, b) once for every pair of \a spans (sorted here) of one orientation
 * that overlap within \a slack on all three axes and of which one has \a changed set
 * (indexed by Span::cell); with \a all_changed every overlapping pair. A sweep along
 * sweepAxis() tests the other two axes per pair; every axis gives the same pairs. */
template <typename Add>
void
mergeCandidatePairs(std::vector<Span>& spans,
                    const std::vector<char>& changed,
                    bool all_changed,
                    float slack,
                    const Add& add)
{
  if (spans.size() < 2)
    return;
  const int d = sweepAxis(spans, slack);
  const int e = (d + 1) % 3, f = (d + 2) % 3;
  const auto order = [d](const Span& a, const Span& b) {
    return std::tie(a.axes, a.lo[d], a.cell) < std::tie(b.axes, b.lo[d], b.cell);
  };
  std::sort(spans.begin(), spans.end(), order);
  const auto test = [&](const Span& a, const Span& b) {
    if (b.lo[e] > a.hi[e] + slack || a.lo[e] > b.hi[e] + slack
        || b.lo[f] > a.hi[f] + slack || a.lo[f] > b.hi[f] + slack)
      return;
    add(a, b);
  };
  if (all_changed) {
    for (std::size_t i = 0; i < spans.size(); ++i)
      for (std::size_t j = i + 1; j < spans.size() && spans[j].axes == spans[i].axes
                                  && spans[j].lo[d] <= spans[i].hi[d] + slack;
           ++j)
        test(spans[i], spans[j]);
    return;
  }
  // Each changed span against the spans whose start on the sweep axis lies within its
  // reach (widened by the longest span, and by slack once more for rounding); a pair of
  // two changed spans is added by the lower cell index.
  float longest = 0.0f;
  for (const Span& span : spans)
    longest = std::max(longest, span.hi[d] - span.lo[d]);
  for (const Span& c : spans) {
    if (!changed[c.cell])
      continue;
    Span from = c;
    from.lo[d] = c.lo[d] - longest - 2.0f * slack;
    from.cell = 0;
    for (auto it = std::lower_bound(spans.begin(), spans.end(), from, order);
         it != spans.end() && it->axes == c.axes && it->lo[d] <= c.hi[d] + slack; ++it)
      if (it->cell != c.cell && !(changed[it->cell] && it->cell < c.cell)
          && !(c.lo[d] > it->hi[d] + slack))
        test(c, *it);
  }
}

} // namespace

void
SurfaceLayer::Impl::pruneAxes()
{
  constexpr std::uint32_t UNUSED = std::numeric_limits<std::uint32_t>::max();
  std::vector<std::uint32_t> renumber(np_axes.size(), UNUSED);
  for (const auto& cell : non_planar)
    renumber[cell.axes] = 0;
  std::uint32_t used = 0;
  for (std::size_t a = 0; a < np_axes.size(); ++a)
    if (renumber[a] != UNUSED) {
      np_axes[used] = np_axes[a];
      renumber[a] = used++;
    }
  if (used == np_axes.size())
    return;
  np_axes.resize(used);
  np_axes.shrink_to_fit();
  for (auto& cell : non_planar)
    cell.axes = renumber[cell.axes];
}

void
SurfaceLayer::Impl::replaceNonPlanar(const std::vector<PlanarCuboid>& incoming,
                                     const Params& params,
                                     std::vector<std::uint32_t>& added)
{
  Impl& impl = *this;
  const double r = params.resolution_m;
  const auto np_bin = static_cast<float>(4.0 * r);
  // 4b. Non-planar replacement (SurfaceLayer's documentation): every stored cell of an
  // earlier frame whose centre lies in a new cuboid grown by half a cell, or that
  // contains the new cuboid's centre, is removed; then the new cells are appended.
  {
    const float half_cell = static_cast<float>(0.5 * r);
    std::vector<std::uint32_t> doomed;
    // A spatial index of the bounding boxes of the stored cells that can meet a new
    // one: those whose box meets the new cells' bounding box grown by half a cell (what
    // this frame sees), so that the work follows the frame, not the whole map. Bins of
    // 4 cells; cells spanning more than MAX_BINS_PER_CUBOID bins in a list tested
    // always.
    std::vector<BinEntry> np_bins;
    std::vector<std::uint32_t> np_large, nearby;
    // the new cells' bounds (also what removeNonPlanarCellsOnPlanes() tests again)
    Eigen::AlignedBox3f incoming_box;
    for (const PlanarCuboid& nw : incoming) {
      Eigen::Vector3f lo, hi;
      cuboidBounds(nw, lo, hi);
      incoming_box.extend(lo);
      incoming_box.extend(hi);
    }
    if (!incoming.empty()) {
      const Eigen::Vector3f region_lo = incoming_box.min().array() - half_cell;
      const Eigen::Vector3f region_hi = incoming_box.max().array() + half_cell;
      for (std::size_t k = 0; k < impl.non_planar.size(); ++k) {
        const auto index = static_cast<std::uint32_t>(k);
        const PlanarCuboid old = impl.nonPlanarCuboid(impl.non_planar[k]);
        Eigen::Vector3f lo, hi;
        cuboidBounds(old, lo, hi);
        if ((lo.array() > region_hi.array()).any()
            || (hi.array() < region_lo.array()).any())
          continue;
        nearby.push_back(index);
        if (!forEachBin(old, 0.0f, np_bin,
                        [&](std::uint64_t key) { np_bins.emplace_back(key, index); }))
          np_large.push_back(index);
      }
      std::sort(np_bins.begin(), np_bins.end());
    }
    // (every stored cell is of an earlier frame)
    const auto test = [&](const PlanarCuboid& nw, std::uint32_t index) {
      const NonPlanarCell& old = impl.non_planar[index];
      if (nw.contains(old.centre, half_cell)
          || impl.nonPlanarCuboid(old).contains(nw.centre))
        doomed.push_back(index);
    };
    for (const PlanarCuboid& nw : incoming) {
      const bool binned = forEachBin(nw, half_cell, np_bin, [&](std::uint64_t key) {
        const auto range =
          std::equal_range(np_bins.begin(), np_bins.end(), BinEntry(key, 0));
        for (auto it = range.first; it != range.second; ++it)
          test(nw, it->index);
      });
      if (binned)
        for (const auto index : np_large)
          test(nw, index);
      else
        for (const auto index : nearby)
          test(nw, index);
    }
    std::vector<BinEntry>().swap(np_bins);
    std::sort(doomed.begin(), doomed.end());
    doomed.erase(std::unique(doomed.begin(), doomed.end()), doomed.end());
    // highest first: the cell moved into a freed slot is never one still to remove
    for (auto it = doomed.rbegin(); it != doomed.rend(); ++it) {
      if (*it + 1 != impl.non_planar.size())
        impl.non_planar[*it] = impl.non_planar.back();
      impl.non_planar.pop_back();
    }
    std::map<AxesKey, std::uint32_t> axes_lookup;
    for (std::size_t a = 0; a < impl.np_axes.size(); ++a)
      axes_lookup.emplace(
        axesKey(impl.np_axes[a].normal, impl.np_axes[a].horizontal_axis),
        static_cast<std::uint32_t>(a));
    impl.non_planar.reserve(impl.non_planar.size() + incoming.size());
    for (const PlanarCuboid& c : incoming) {
      added.push_back(static_cast<std::uint32_t>(impl.non_planar.size()));
      impl.non_planar.emplace_back(c, impl.internAxes(c, axes_lookup));
    }
    impl.tidy_added.extend(incoming_box);
    if (!doomed.empty())
      impl.pruneAxes();
    impl.non_planar.shrink_to_fit();
  }
}

std::size_t
SurfaceLayer::removeNonPlanarCells(
  const std::function<bool(const PlanarCuboid&)>& remove)
{
  Impl& impl = *impl_;
  std::lock_guard<std::mutex> lock(impl.mutex);
  std::size_t kept = 0;
  for (std::size_t k = 0; k < impl.non_planar.size(); ++k)
    if (!remove(impl.nonPlanarCuboid(impl.non_planar[k])))
      impl.non_planar[kept++] = impl.non_planar[k];
  const std::size_t removed = impl.non_planar.size() - kept;
  if (removed == 0)
    return 0;
  impl.non_planar.erase(impl.non_planar.begin() + static_cast<std::ptrdiff_t>(kept),
                        impl.non_planar.end());
  impl.pruneAxes();
  impl.non_planar.shrink_to_fit();
  impl.invalidate();
  return removed;
}

std::size_t
SurfaceLayer::mergeNonPlanarCells(
  const std::function<bool(const PlanarCuboid&)>& candidate,
  const std::function<bool(const PlanarCuboid&)>& accept,
  double min_fill)
{
  if (!(min_fill >= 0.0 && min_fill <= 1.0))
    throw Exception(
      "SurfaceLayer::mergeNonPlanarCells: min_fill must be in [0, 1], got "
      + formatParamNumber(min_fill));
  Impl& impl = *impl_;
  std::lock_guard<std::mutex> lock(impl.mutex);
  const std::size_t before = impl.non_planar.size();
  const auto slack = static_cast<float>(0.5 * params_.resolution_m);
  const auto spanOf = [&](std::uint32_t k) {
    const NonPlanarCell& cell = impl.non_planar[k];
    const BoxAxes& axes = impl.np_axes[cell.axes];
    const Eigen::Vector3f vertical = axes.normal.cross(axes.horizontal_axis);
    const Eigen::Vector3f local(axes.horizontal_axis.dot(cell.centre),
                                vertical.dot(cell.centre),
                                axes.normal.dot(cell.centre));
    const Eigen::Vector3f half =
      0.5f * Eigen::Vector3f(cell.width_m, cell.height_m, cell.thickness_m);
    return Span{k, cell.axes, local - half, local + half};
  };
  const auto boxOf = [&](std::uint32_t axes_index, const Eigen::Vector3f& lo,
                         const Eigen::Vector3f& hi) {
    const BoxAxes& axes = impl.np_axes[axes_index];
    const Eigen::Vector3f vertical = axes.normal.cross(axes.horizontal_axis);
    const Eigen::Vector3f mid = 0.5f * (lo + hi);
    PlanarCuboid c;
    c.centre =
      axes.horizontal_axis * mid.x() + vertical * mid.y() + axes.normal * mid.z();
    c.normal = axes.normal;
    c.horizontal_axis = axes.horizontal_axis;
    const Eigen::Vector3f size = hi - lo;
    c.width_m = size.x();
    c.height_m = size.y();
    c.thickness_m = size.z();
    return c;
  };

  std::vector<std::uint32_t> live;
  for (std::size_t k = 0; k < before; ++k)
    if (candidate(impl.nonPlanarCuboid(impl.non_planar[k])))
      live.push_back(static_cast<std::uint32_t>(k));
  std::vector<char> removed(before, 0);
  // The volume each cell's parts fill (overlaps counted once): at the start its own
  // volume, so that a cell merged in an earlier call counts as filled. A merged box
  // must be filled to at least min_fill.
  std::vector<float> filled(before, 0.0f);
  for (const std::uint32_t k : live) {
    const NonPlanarCell& cell = impl.non_planar[k];
    filled[k] = cell.width_m * cell.height_m * cell.thickness_m;
  }
  // A cell's generation rises when it grows, so that a pair refused once is tested
  // again only when one of its cells changed.
  std::vector<std::uint32_t> generation(before, 0);
  std::set<std::array<std::uint32_t, 4>> refused;
  std::vector<Span> spans;
  std::vector<std::tuple<float, std::uint32_t, std::uint32_t>> pairs;
  std::vector<char> used(before, 0);
  // The cells that grew in the last pass. Only a pair with one of them can be new: a
  // pair of two unchanged cells was enumerated in that pass, and was refused then
  // (refused stays refused) or skipped because one of its cells merged (it changed).
  std::vector<char> changed(before, 1);
  bool merged = true;
  bool first_pass = true;
  while (merged && live.size() > 1) {
    merged = false;
    spans.clear();
    for (const std::uint32_t k : live)
      spans.push_back(spanOf(k));
    pairs.clear();
    mergeCandidatePairs(
      spans, changed, first_pass, slack, [&](const Span& a, const Span& b) {
        const std::uint32_t first = std::min(a.cell, b.cell);
        const std::uint32_t second = std::max(a.cell, b.cell);
        if (refused.count({first, generation[first], second, generation[second]}) > 0)
          return;
        const Eigen::Vector3f size = a.hi.cwiseMax(b.hi) - a.lo.cwiseMin(b.lo);
        pairs.emplace_back(size.prod(), first, second);
      });
    first_pass = false;
    std::fill(changed.begin(), changed.end(), 0);
    std::sort(pairs.begin(), pairs.end());
    std::fill(used.begin(), used.end(), 0);
    for (const auto& [volume, first, second] : pairs) {
      static_cast<void>(volume); // the sort key
      if (used[first] || used[second])
        continue;
      const Span a = spanOf(first);
      const Span b = spanOf(second);
      const Eigen::Vector3f lo = a.lo.cwiseMin(b.lo);
      const Eigen::Vector3f hi = a.hi.cwiseMax(b.hi);
      const Eigen::Vector3f overlap =
        (a.hi.cwiseMin(b.hi) - a.lo.cwiseMax(b.lo)).cwiseMax(0.0f);
      const float fill = filled[first] + filled[second] - overlap.prod();
      const PlanarCuboid box = boxOf(a.axes, lo, hi);
      if (static_cast<double>(fill) < min_fill * static_cast<double>((hi - lo).prod())
          || !accept(box)) {
        refused.insert({first, generation[first], second, generation[second]});
        continue;
      }
      NonPlanarCell& cell = impl.non_planar[first];
      const NonPlanarCell& gone = impl.non_planar[second];
      cell.centre = box.centre;
      cell.width_m = box.width_m;
      cell.height_m = box.height_m;
      cell.thickness_m = box.thickness_m;
      cell.feature_count += gone.feature_count;
      cell.probability_sum += gone.probability_sum;
      filled[first] = fill;
      ++generation[first];
      changed[first] = 1;
      removed[second] = 1;
      used[first] = used[second] = 1;
      Eigen::Vector3f box_lo, box_hi;
      cuboidBounds(box, box_lo, box_hi);
      impl.tidy_added.extend(box_lo);
      impl.tidy_added.extend(box_hi);
      merged = true;
    }
    live.erase(std::remove_if(live.begin(), live.end(),
                              [&](std::uint32_t k) { return removed[k] != 0; }),
               live.end());
  }
  std::size_t kept = 0;
  for (std::size_t k = 0; k < before; ++k)
    if (!removed[k])
      impl.non_planar[kept++] = impl.non_planar[k];
  if (kept == before)
    return 0;
  impl.non_planar.erase(impl.non_planar.begin() + static_cast<std::ptrdiff_t>(kept),
                        impl.non_planar.end());
  impl.non_planar.shrink_to_fit();
  impl.invalidate();
  return before - kept;
}

std::size_t
SurfaceLayer::removeNonPlanarCellsOnPlanes()
{
  const auto r = static_cast<float>(params_.resolution_m);
  const float half_cell = 0.5f * r;
  const float bin = 8.0f * r;
  PlanarCuboids planar;
  std::vector<BinEntry> bins;
  std::vector<std::uint32_t> large; // cuboids spanning too many bins: tested always
  // Where a cell's centre and footprint samples can reach: its box grown by its
  // half-diagonal twice over and half a cell (the samples lie within the diagonal of
  // the centre; a cuboid holds a point within half a cell).
  const auto reachBox = [half_cell](const PlanarCuboid& cell) {
    Eigen::Vector3f lo, hi;
    cuboidBounds(cell, lo, hi);
    const float grow =
      Eigen::Vector3f(cell.width_m, cell.height_m, cell.thickness_m).norm() + half_cell;
    return Eigen::AlignedBox3f(lo.array() - grow, hi.array() + grow);
  };
  // Only the cells reaching into the region that changed since the last call can have
  // come to lie on a plane (Impl::tidy_all), and only the planar cuboids within their
  // reach can hold them.
  bool all = false;
  Eigen::AlignedBox3f changed, candidates;
  {
    std::lock_guard<std::mutex> lock(impl_->mutex);
    Impl& impl = *impl_;
    impl.buildPlanarCuboids(params_, planar);
    all = impl.tidy_all;
    changed = impl.tidy_added;
    for (const PlanarCuboid& c : planar)
      if (impl.planes[static_cast<std::size_t>(c.plane_id)].tidy_pending) {
        Eigen::Vector3f lo, hi;
        cuboidBounds(c, lo, hi);
        changed.extend(lo);
        changed.extend(hi);
      }
    impl.tidy_all = false;
    impl.tidy_added.setEmpty();
    for (auto& plane : impl.planes)
      plane.tidy_pending = false;
    if (impl.non_planar.empty() || planar.empty())
      return 0;
    if (!all) {
      for (const auto& cell : impl.non_planar) {
        const Eigen::AlignedBox3f reach = reachBox(impl.nonPlanarCuboid(cell));
        if (reach.intersects(changed))
          candidates.extend(reach);
      }
      if (candidates.isEmpty())
        return 0;
    }
  }
  if (!all) {
    // (the cuboids keep their order: the first holding a point stays the first)
    std::size_t kept = 0;
    for (std::size_t k = 0; k < planar.size(); ++k) {
      Eigen::Vector3f lo, hi;
      cuboidBounds(planar[k], lo, hi);
      if (candidates.intersects(Eigen::AlignedBox3f(lo, hi)))
        planar[kept++] = planar[k];
    }
    planar.resize(kept);
    if (planar.empty())
      return 0;
  }
  // in index order within a bin, so that the first cuboid holding a point is the
  // same on every run
  binCuboids(planar, half_cell, bin, bins, large);
  // The first planar cuboid of plane \a plane_id (any plane for -1) that holds \a q
  // within half a cell, or -1.
  const auto onPlane = [&](const Eigen::Vector3f& q, int plane_id) -> std::ptrdiff_t {
    const auto holds = [&](std::uint32_t k) {
      return (plane_id < 0 || planar[k].plane_id == plane_id)
             && planar[k].contains(q, half_cell);
    };
    // the bin as forEachBin() computes it, so a point inside a grown box finds it
    const Eigen::Vector3d b = binOf(q, bin);
    const std::uint64_t key =
      binKey(static_cast<std::int64_t>(b.x()), static_cast<std::int64_t>(b.y()),
             static_cast<std::int64_t>(b.z()));
    const auto range = std::equal_range(bins.begin(), bins.end(), BinEntry(key, 0));
    for (auto it = range.first; it != range.second; ++it)
      if (holds(it->index))
        return static_cast<std::ptrdiff_t>(it->index);
    for (const auto k : large)
      if (holds(k))
        return static_cast<std::ptrdiff_t>(k);
    return -1;
  };
  return removeNonPlanarCells([&](const PlanarCuboid& cell) {
    if (!all && !reachBox(cell).intersects(changed))
      return false;
    const std::ptrdiff_t first = onPlane(cell.centre, -1);
    if (first < 0)
      return false;
    // The cell's footprint on that plane, sampled at most a cell apart (its corners
    // included), must lie on the plane's cuboids: the plane holds all of it.
    const PlanarCuboid& c = planar[static_cast<std::size_t>(first)];
    const Eigen::Vector3f u = c.horizontal_axis, v = c.verticalAxis();
    const Eigen::Vector3f cell_u = 0.5f * cell.width_m * cell.horizontal_axis;
    const Eigen::Vector3f cell_v = 0.5f * cell.height_m * cell.verticalAxis();
    const Eigen::Vector3f cell_n = 0.5f * cell.thickness_m * cell.normal;
    const auto reach = [&](const Eigen::Vector3f& a) {
      return std::abs(cell_u.dot(a)) + std::abs(cell_v.dot(a))
             + std::abs(cell_n.dot(a));
    };
    const float reach_u = reach(u), reach_v = reach(v);
    const float span_u = std::ceil(2.0f * reach_u / r);
    const float span_v = std::ceil(2.0f * reach_v / r);
    if (!(span_u <= 64.0f) || !(span_v <= 64.0f))
      return false; // far larger than the planes' cells: not a repeat of a surface
    const int steps_u = static_cast<int>(span_u);
    const int steps_v = static_cast<int>(span_v);
    for (int a = 0; a <= steps_u; ++a)
      for (int b = 0; b <= steps_v; ++b) {
        const float du = steps_u > 0 ? -reach_u + 2.0f * reach_u * a / steps_u : 0.0f;
        const float dv = steps_v > 0 ? -reach_v + 2.0f * reach_v * b / steps_v : 0.0f;
        if (onPlane(cell.centre + du * u + dv * v, c.plane_id) < 0)
          return false;
      }
    return true;
  });
}

void
SurfaceLayer::Impl::ensureIsolated(const Params& params)
{
  if (isolated_valid)
    return;
  isolated.clear();
  isolated_valid = true;
  if (!params.skip_isolated_non_planar || non_planar.empty())
    return;
  const double r = params.resolution_m;
  const double one_voxel = 1.5 * r * r * r;
  const auto reach = static_cast<float>(r);
  const auto bin = static_cast<float>(4.0 * r);
  // The one-voxel cells, by the bin of their centre.
  const auto binOfCentre = [bin](const Eigen::Vector3f& p) {
    const Eigen::Vector3d b = binOf(p, bin);
    return binKey(static_cast<std::int64_t>(b.x()), static_cast<std::int64_t>(b.y()),
                  static_cast<std::int64_t>(b.z()));
  };
  std::vector<BinEntry> singles;
  for (std::size_t k = 0; k < non_planar.size(); ++k) {
    const NonPlanarCell& cell = non_planar[k];
    if (static_cast<double>(cell.width_m) * cell.height_m * cell.thickness_m
        <= one_voxel)
      singles.emplace_back(binOfCentre(cell.centre), static_cast<std::uint32_t>(k));
  }
  if (singles.empty())
    return;
  std::sort(singles.begin(), singles.end(), [](const BinEntry& a, const BinEntry& b) {
    return a.key() < b.key() || (a.key() == b.key() && a.index < b.index);
  });
  // bin key -> the singles' range [first, last) in that bin
  std::unordered_map<std::uint64_t, std::pair<std::uint32_t, std::uint32_t>> ranges;
  ranges.reserve(singles.size());
  for (std::size_t s = 0; s < singles.size();) {
    std::size_t e = s + 1;
    while (e < singles.size() && singles[e].key() == singles[s].key())
      ++e;
    ranges.emplace(singles[s].key(), std::make_pair(static_cast<std::uint32_t>(s),
                                                    static_cast<std::uint32_t>(e)));
    s = e;
  }
  // Each cuboid, grown by one cell, marks the singles whose centres it holds: a
  // neighbouring lattice voxel lies within half a cell of a single's centre, the next
  // one out 1.5 cells away. Only the bins the grown cuboid meets are looked at.
  std::vector<std::uint8_t> touched(singles.size(), 0);
  const auto mark = [&](const PlanarCuboid& c, std::uint32_t self) {
    const auto markIn = [&](std::size_t s) {
      if (!touched[s] && singles[s].index != self
          && c.contains(non_planar[singles[s].index].centre, reach))
        touched[s] = 1;
    };
    const bool binned = forEachBin(c, reach, bin, [&](std::uint64_t key) {
      const auto it = ranges.find(key);
      if (it != ranges.end())
        for (std::uint32_t s = it->second.first; s < it->second.second; ++s)
          markIn(s);
    });
    if (!binned)
      for (std::size_t s = 0; s < singles.size(); ++s)
        markIn(s);
  };
  // The planes' rectangles (large and thin, their bins many) are tested plane by
  // plane against the singles near the plane: a rectangle's face lies on its plane and
  // its box reaches thickness behind, so a centre it holds within one cell lies
  // within thickness + one cell of the plane (half a cell more for rounding).
  PlanarCuboids planar;
  buildPlanarCuboids(params, planar);
  for (std::size_t first = 0; first < planar.size();) {
    const int plane_id = planar[first].plane_id;
    std::size_t last = first;
    float thickness = 0.0f;
    while (last < planar.size() && planar[last].plane_id == plane_id)
      thickness = std::max(thickness, planar[last++].thickness_m);
    const MapPlane& plane = planes[static_cast<std::size_t>(plane_id)];
    const float near = thickness + 1.5f * reach;
    for (std::size_t s = 0; s < singles.size(); ++s) {
      if (touched[s])
        continue;
      const Eigen::Vector3f& p = non_planar[singles[s].index].centre;
      if (std::abs(plane.normal.dot(p) + plane.d) > near)
        continue;
      for (std::size_t j = first; j < last && !touched[s]; ++j)
        if (planar[j].contains(p, reach))
          touched[s] = 1;
    }
    first = last;
  }
  for (std::size_t k = 0; k < non_planar.size(); ++k)
    mark(nonPlanarCuboid(non_planar[k]), static_cast<std::uint32_t>(k));
  for (std::size_t s = 0; s < singles.size(); ++s)
    if (!touched[s])
      isolated.push_back(singles[s].index);
  std::sort(isolated.begin(), isolated.end());
  isolated.shrink_to_fit();
}

} // namespace planar_grid
