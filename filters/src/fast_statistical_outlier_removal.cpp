// SPDX-License-Identifier: BSD-3-Clause
#include <planar_grid/filters/fast_statistical_outlier_removal.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>
#include <nanoflann.hpp>
#include <vector>

namespace planar_grid {

namespace {

/** nanoflann's view of packed x, y, z triples: distance computations read one
 * contiguous array instead of the cloud through an index list. */
struct PackedPoints {
  const std::vector<float>& xyz;

  std::size_t kdtree_get_point_count() const { return xyz.size() / 3; }
  float kdtree_get_pt(std::size_t i, std::size_t dim) const { return xyz[3 * i + dim]; }
  template <typename BoundingBox> bool kdtree_get_bbox(BoundingBox&) const
  {
    return false;
  }
};

/** Points per leaf of the kd-tree. The tree answers only a sample and the few points
 * the cells cannot, so its build dominates: larger leaves mean fewer levels to
 * partition, and any leaf size gives the same exact neighbours. */
constexpr std::size_t TREE_LEAF_SIZE = 256;

/** Integer cell coordinates packed into one key, 21 bits per axis. */
std::uint64_t
cellKey(std::int64_t x, std::int64_t y, std::int64_t z)
{
  constexpr std::int64_t OFFSET = std::int64_t{1} << 20;
  return (static_cast<std::uint64_t>(x + OFFSET) << 42)
         | (static_cast<std::uint64_t>(y + OFFSET) << 21)
         | static_cast<std::uint64_t>(z + OFFSET);
}

/** The squared distance bound of a point's selection as a multiple of its
 * neighbour's squared k-th distance: the neighbour's k-th distance itself, which
 * holds about k candidates, so that the selection has few to take out. */
constexpr float BOUND_PER_KTH_SQ = 1.0f;

/** When fewer than k candidates lie below the bound, it is widened by this factor
 * (squared distances) up to WIDEN_FINE_STEPS times, then doubled: small steps keep
 * the candidates taken near k, doubling bounds the passes when the bound was far too
 * small. */
constexpr float WIDEN_FINE_FACTOR = 1.1f;
constexpr int WIDEN_FINE_STEPS = 4;

/** Most candidates taken out above the k nearest in one pass; with more, the k-th is
 * selected instead. */
constexpr std::size_t MAX_DROPPED = 16;

/** The cell edge as a multiple of the median k-th neighbour distance: small enough for
 * few candidates, large enough that most points of a surface are answered by cells. */
constexpr double CELL_EDGE_PER_KTH_DISTANCE = 1.25;

/** \brief The cell edge for the cell search: CELL_EDGE_PER_KTH_DISTANCE times the
 * median k-th neighbour distance of a sample of 256 points (the tree's answers);
 * \a median_kth_sq receives that median, squared. Not positive and finite when the
 * sample gives no edge. */
template <typename Tree>
double
cellEdge(const std::vector<float>& xyz,
         const Tree& tree,
         std::size_t k,
         float& median_kth_sq)
{
  const std::size_t n = xyz.size() / 3;
  std::vector<float> kth_sq;
  std::vector<std::uint32_t> nn_indices(k);
  std::vector<float> nn_dists(k);
  const std::size_t step = std::max<std::size_t>(1, n / 256);
  for (std::size_t j = 0; j < n; j += step) {
    nanoflann::KNNResultSet<float, std::uint32_t> result(k);
    result.init(nn_indices.data(), nn_dists.data());
    tree.findNeighbors(result, &xyz[3 * j], nanoflann::SearchParams());
    kth_sq.push_back(nn_dists[result.size() - 1]);
  }
  const auto median = kth_sq.begin() + static_cast<std::ptrdiff_t>(kth_sq.size() / 2);
  std::nth_element(kth_sq.begin(), median, kth_sq.end());
  median_kth_sq = *median;
  return CELL_EDGE_PER_KTH_DISTANCE * std::sqrt(static_cast<double>(*median));
}

/** \brief The points sorted into cubic cells: every point's cell, the points in cell
 * order with their coordinates copied in that order, and the cells as a sorted key
 * list with the range of their points. The cells of one x, y column are consecutive
 * keys (z is the lowest field), so a column of cells is one search. */
struct CellIndex {
  double edge{0.0};
  /** \brief Cell coordinates of point j at 3 j .. 3 j + 2. */
  std::vector<std::int64_t> cell;
  /** \brief The points in cell order. */
  std::vector<std::uint32_t> order;
  std::vector<float> sorted_x, sorted_y, sorted_z;
  std::vector<std::uint64_t> cell_keys;
  /** \brief Cell c's points are order[cell_begin[c] .. cell_begin[c + 1]). */
  std::vector<std::uint32_t> cell_begin;

  /** \brief A point's cell key and index, and the key's rank within the cells' bounding
   * box (for the radix sort). */
  struct KeyedPoint {
    std::uint64_t key;
    std::uint32_t index;
    std::uint32_t rank;
  };

  /** \brief Sorts \a points by key. When the cells' bounding box (\a lowest ..
   * \a highest cell coordinates) has fewer than 2^32 cells, by a least significant
   * digit radix sort of each key's rank in the box (x, then y, then z, as the keys
   * order them), 11 bits a pass; otherwise by std::sort. The order of the points of one
   * cell is left open: every answer is the same for any order. */
  static void sortByKey(std::vector<KeyedPoint>& points,
                        const std::int64_t* lowest,
                        const std::int64_t* highest)
  {
    const auto width = [&](std::size_t d) {
      return static_cast<std::uint64_t>(highest[d] - lowest[d]) + 1;
    };
    // Each width is below 2^21, so the products below fit 64 bits.
    const std::uint64_t box = width(0) * width(1) * width(2);
    if (points.empty() || box > (std::uint64_t{1} << 32)) {
      std::sort(points.begin(), points.end(),
                [](const KeyedPoint& a, const KeyedPoint& b) { return a.key < b.key; });
      return;
    }
    constexpr std::uint64_t OFFSET = std::uint64_t{1} << 20;
    constexpr std::uint64_t FIELD = (std::uint64_t{1} << 21) - 1;
    for (KeyedPoint& p : points) {
      const std::uint64_t x =
        (p.key >> 42) - static_cast<std::uint64_t>(lowest[0] + OFFSET);
      const std::uint64_t y =
        ((p.key >> 21) & FIELD) - static_cast<std::uint64_t>(lowest[1] + OFFSET);
      const std::uint64_t z =
        (p.key & FIELD) - static_cast<std::uint64_t>(lowest[2] + OFFSET);
      p.rank = static_cast<std::uint32_t>((x * width(1) + y) * width(2) + z);
    }
    constexpr unsigned DIGIT_BITS = 11;
    constexpr std::size_t BUCKETS = std::size_t{1} << DIGIT_BITS;
    std::vector<KeyedPoint> buffer(points.size());
    std::vector<std::size_t> count(BUCKETS);
    for (unsigned shift = 0; shift < 32 && (box - 1) >> shift != 0;
         shift += DIGIT_BITS) {
      std::fill(count.begin(), count.end(), 0);
      for (const KeyedPoint& p : points)
        ++count[(p.rank >> shift) & (BUCKETS - 1)];
      std::size_t start = 0;
      for (std::size_t& c : count) {
        const std::size_t here = c;
        c = start;
        start += here;
      }
      for (const KeyedPoint& p : points)
        buffer[count[(p.rank >> shift) & (BUCKETS - 1)]++] = p;
      points.swap(buffer);
    }
  }

  /** \brief Sorts the points of \a xyz into cells of edge \a cell_edge (meters);
   * false when a cell's key would not fit 21 bits per axis (the cloud is too
   * large). */
  bool build(const std::vector<float>& xyz, double cell_edge)
  {
    edge = cell_edge;
    const std::size_t n = xyz.size() / 3;
    // Keys of the cells up to 2 away from any point stay within 21 bits per axis.
    constexpr double MAX_CELL = static_cast<double>((1 << 20) - 3);
    cell.resize(3 * n);
    std::vector<KeyedPoint> sorted(n);
    std::int64_t lowest[3] = {0, 0, 0}, highest[3] = {0, 0, 0};
    for (std::size_t j = 0; j < n; ++j) {
      for (std::size_t d = 0; d < 3; ++d) {
        const double c = std::floor(static_cast<double>(xyz[3 * j + d]) / edge);
        if (!(std::abs(c) <= MAX_CELL))
          return false;
        const auto ci = static_cast<std::int64_t>(c);
        cell[3 * j + d] = ci;
        lowest[d] = j == 0 ? ci : std::min(lowest[d], ci);
        highest[d] = j == 0 ? ci : std::max(highest[d], ci);
      }
      sorted[j] = {cellKey(cell[3 * j], cell[3 * j + 1], cell[3 * j + 2]),
                   static_cast<std::uint32_t>(j), 0};
    }
    sortByKey(sorted, lowest, highest);
    order.resize(n);
    sorted_x.resize(n);
    sorted_y.resize(n);
    sorted_z.resize(n);
    for (std::size_t i = 0; i < n; ++i) {
      const std::uint32_t j = sorted[i].index;
      order[i] = j;
      sorted_x[i] = xyz[3 * j];
      sorted_y[i] = xyz[3 * j + 1];
      sorted_z[i] = xyz[3 * j + 2];
      if (i == 0 || sorted[i].key != sorted[i - 1].key) {
        cell_keys.push_back(sorted[i].key);
        cell_begin.push_back(static_cast<std::uint32_t>(i));
      }
    }
    cell_begin.push_back(static_cast<std::uint32_t>(n));
    return true;
  }
};

/** \brief Answers points' k nearest neighbours from the candidates of the cells
 * around their cell (the points of the 3 x 3 x 3 or 5 x 5 x 5 cells, gathered once
 * per cell). */
class CellNeighbours {
public:
  CellNeighbours(const CellIndex& index, std::size_t k, int mean_k) :
      index_(index), k_(k), mean_k_(mean_k)
  {}

  /** \brief Gathers the candidates of the cells within \a reach of cell \a c,
   * coordinate by coordinate, so that the distance loop runs over contiguous arrays.
   * The cells are found column by column (one search each, starting where the
   * previous column's ended: the columns come in increasing key order), then their
   * points appended z slice by z slice, y row by y row, x cell by x cell, so that the
   * candidates (and the order in which the selected distances are summed) are those
   * of a cell by cell walk in that order. */
  void gather(const std::int64_t* c, std::int64_t reach)
  {
    constexpr std::size_t NO_CELL = std::numeric_limits<std::size_t>::max();
    const auto& cell_keys = index_.cell_keys;
    const auto width = static_cast<std::size_t>(2 * reach + 1);
    found_.assign(width * width * width, NO_CELL);
    auto from = cell_keys.begin();
    for (std::int64_t dx = -reach; dx <= reach; ++dx)
      for (std::int64_t dy = -reach; dy <= reach; ++dy) {
        const std::uint64_t first = cellKey(c[0] + dx, c[1] + dy, c[2] - reach);
        from = std::lower_bound(from, cell_keys.end(), first);
        for (; from != cell_keys.end() && *from - first < width; ++from) {
          const auto dz = static_cast<std::size_t>(*from - first);
          const auto row = static_cast<std::size_t>(dy + reach);
          const auto col = static_cast<std::size_t>(dx + reach);
          found_[(dz * width + row) * width + col] =
            static_cast<std::size_t>(from - cell_keys.begin());
        }
      }
    cand_x_.clear();
    cand_y_.clear();
    cand_z_.clear();
    for (const std::size_t cell_index : found_) {
      if (cell_index == NO_CELL)
        continue;
      const auto b = static_cast<std::ptrdiff_t>(index_.cell_begin[cell_index]);
      const auto e = static_cast<std::ptrdiff_t>(index_.cell_begin[cell_index + 1]);
      cand_x_.insert(cand_x_.end(), index_.sorted_x.begin() + b,
                     index_.sorted_x.begin() + e);
      cand_y_.insert(cand_y_.end(), index_.sorted_y.begin() + b,
                     index_.sorted_y.begin() + e);
      cand_z_.insert(cand_z_.end(), index_.sorted_z.begin() + b,
                     index_.sorted_z.begin() + e);
    }
    d2_.resize(cand_x_.size());
    near_.resize(cand_x_.size());
  }

  /** \brief Answers the point at \a i in cell order (point j = order[i]) from the
   * candidates gathered for its cell \a c within \a reach into mean_distance[j] and
   * done[j]; false when fewer than k candidates lie within the guard. \a bound_sq,
   * the previous point's k-th distance squared times BOUND_PER_KTH_SQ, limits the
   * selection and is updated. */
  bool answer(std::size_t i,
              const std::int64_t* c,
              std::int64_t reach,
              float& bound_sq,
              std::vector<float>& mean_distance,
              std::vector<char>& done)
  {
    const std::size_t m = cand_x_.size();
    if (m < k_)
      return false;
    const std::uint32_t j = index_.order[i];
    // The point's coordinates from the arrays in cell order, read in sequence.
    const float q[3] = {index_.sorted_x[i], index_.sorted_y[i], index_.sorted_z[i]};
    // Distance from q to the outside of the cells, with a margin for the rounding of
    // the single precision distances; only candidates within it can be among the k
    // nearest.
    const double r = static_cast<double>(reach);
    const double edge = index_.edge;
    double guard = std::numeric_limits<double>::max();
    for (std::size_t d = 0; d < 3; ++d) {
      const double lo = static_cast<double>(c[d]) * edge;
      const double x = static_cast<double>(q[d]);
      guard = std::min(guard, r * edge + std::min(x - lo, lo + edge - x));
    }
    // In single precision: the margin is far larger than the rounding of the bound.
    const auto guard_sq = static_cast<float>(guard * guard * (1.0 - 2e-6));
    const std::size_t inside = candidatesWithin(q, guard_sq, bound_sq);
    if (inside < k_)
      return false;
    const float kth = keepKSmallest(inside);
    // A dropped candidate (-1) adds sqrt(0) = +0, which leaves the sum unchanged:
    // the sum of the k kept, in candidate order, without a branch.
    double dist_sum = 0.0;
    for (std::size_t t = 0; t < inside; ++t)
      dist_sum += std::sqrt(std::max(near_[t], 0.0f));
    mean_distance[j] = static_cast<float>(dist_sum / mean_k_);
    done[j] = 1;
    bound_sq = BOUND_PER_KTH_SQ * kth;
    return true;
  }

private:
  /** \brief The squared distances from \a q to the candidates below \a bound_sq (and
   * within \a guard_sq) into near_[0 .. returned count). When at least k are, they
   * hold the k nearest: every other candidate is farther than all of them. Too few
   * below the bound: the bound widened (the distances are kept), up to the guard. */
  std::size_t candidatesWithin(const float* q, float guard_sq, float bound_sq)
  {
    const std::size_t m = cand_x_.size();
    // The squared distance as nanoflann's L2_Simple_Adaptor computes it: single
    // precision, summed over x, y, z in that order.
    const float tight_sq = std::min(guard_sq, bound_sq);
    const float qx = q[0], qy = q[1], qz = q[2];
    // The distances in a loop of their own, which the compiler vectorises (the same
    // operations per candidate), then the ones below the bound.
    const float *cx = cand_x_.data(), *cy = cand_y_.data(), *cz = cand_z_.data();
    float* const dist = d2_.data();
    float* const near = near_.data();
    for (std::size_t t = 0; t < m; ++t) {
      const float ex = qx - cx[t], ey = qy - cy[t], ez = qz - cz[t];
      float sq = ex * ex;
      sq += ey * ey;
      sq += ez * ez;
      dist[t] = sq;
    }
    std::size_t inside = 0;
    for (std::size_t t = 0; t < m; ++t) {
      near[inside] = dist[t];
      inside += dist[t] < tight_sq ? 1 : 0;
    }
    int steps = 0;
    for (float wider_sq = tight_sq; inside < k_ && wider_sq < guard_sq; ++steps) {
      const float factor = steps < WIDEN_FINE_STEPS ? WIDEN_FINE_FACTOR : 2.0f;
      wider_sq = wider_sq > 0.0f ? std::min(guard_sq, factor * wider_sq) : guard_sq;
      inside = 0;
      for (std::size_t t = 0; t < m; ++t) {
        near[inside] = dist[t];
        inside += dist[t] < wider_sq ? 1 : 0;
      }
    }
    return inside;
  }

  /** \brief Of near_[0 .. inside), marks all but the k smallest with -1 and returns
   * the k-th: the few largest are found in one pass and taken out (most points), or
   * the k-th is selected when many are left. */
  float keepKSmallest(std::size_t inside)
  {
    float kth = 0.0f;
    const std::size_t drop = inside - k_;
    if (drop <= MAX_DROPPED) {
      // The drop largest so far, ascending, and where they are.
      float top[MAX_DROPPED];
      std::size_t at[MAX_DROPPED];
      std::size_t filled = 0;
      for (std::size_t t = 0; t < inside && drop > 0; ++t) {
        const float v = near_[t];
        std::size_t p;
        if (filled < drop) {
          for (p = filled++; p > 0 && top[p - 1] > v; --p) {
            top[p] = top[p - 1];
            at[p] = at[p - 1];
          }
        } else if (v > top[0]) {
          for (p = 0; p + 1 < drop && top[p + 1] < v; ++p) {
            top[p] = top[p + 1];
            at[p] = at[p + 1];
          }
        } else
          continue;
        top[p] = v;
        at[p] = t;
      }
      for (std::size_t q = 0; q < drop; ++q)
        near_[at[q]] = -1.0f;
      for (std::size_t t = 0; t < inside; ++t)
        kth = std::max(kth, near_[t]);
    } else {
      const auto it = near_.begin() + static_cast<std::ptrdiff_t>(k_ - 1);
      std::nth_element(near_.begin(), it,
                       near_.begin() + static_cast<std::ptrdiff_t>(inside));
      kth = *it;
      std::fill(it + 1, near_.begin() + static_cast<std::ptrdiff_t>(inside), -1.0f);
    }
    return kth;
  }

  const CellIndex& index_;
  const std::size_t k_;
  const int mean_k_;
  std::vector<std::size_t> found_;
  std::vector<float> cand_x_, cand_y_, cand_z_, d2_, near_;
};

/** \brief Mean distances of the queried points to their k - 1 nearest other points,
 * found among the points of the 3 x 3 x 3 cells around each point's cell, or else of
 * the 5 x 5 x 5 cells.
 *
 * A point is answered (done[j] set) only when its k-th distance (itself included) is
 * shorter than the distance from the point to the outside of those cells: no point
 * elsewhere can then be nearer, and the k smallest distances are the kd-tree's. Their
 * sum of single precision distances in double precision is exact, whatever their
 * order, so mean_distance[j] equals the tree's answer bit for bit. The other points
 * are left to the tree. */
template <typename Tree>
void
meanDistancesInCells(const std::vector<float>& xyz,
                     const Tree& tree,
                     const std::vector<char>& queried,
                     std::size_t k,
                     int mean_k,
                     std::vector<float>& mean_distance,
                     std::vector<char>& done)
{
  float median_kth_sq = 0.0f;
  const double edge = cellEdge(xyz, tree, k, median_kth_sq);
  if (!(edge > 0.0) || !std::isfinite(edge))
    return;
  CellIndex index;
  if (!index.build(xyz, edge))
    return; // the cloud is too large for the keys: the tree answers all
  CellNeighbours neighbours(index, k, mean_k);
  // The k-th distance of the previous point of the same cell, squared: a close
  // neighbour's k-th distance is nearly the same, so the candidates below
  // BOUND_PER_KTH_SQ times it usually hold the k nearest, and the selection runs over
  // those few.
  const float first_bound_sq = BOUND_PER_KTH_SQ * median_kth_sq;
  std::vector<std::size_t> missed; // positions in cell order
  for (std::size_t cell_index = 0; cell_index < index.cell_keys.size(); ++cell_index) {
    const std::size_t run_begin = index.cell_begin[cell_index];
    const std::size_t run_end = index.cell_begin[cell_index + 1];
    const auto run = index.order.begin() + static_cast<std::ptrdiff_t>(run_begin);
    if (std::none_of(run, run + static_cast<std::ptrdiff_t>(run_end - run_begin),
                     [&queried](std::uint32_t j) { return queried[j] != 0; }))
      continue;
    const std::int64_t* c = &index.cell[3 * index.order[run_begin]];
    // The 3 x 3 x 3 cells answer most points; the 5 x 5 x 5 cells most of the rest,
    // where the points are sparse (and so are the candidates).
    neighbours.gather(c, 1);
    missed.clear();
    float bound_sq = first_bound_sq;
    for (std::size_t i = run_begin; i < run_end; ++i)
      if (queried[index.order[i]]
          && !neighbours.answer(i, c, 1, bound_sq, mean_distance, done))
        missed.push_back(i);
    if (missed.empty())
      continue;
    neighbours.gather(c, 2);
    bound_sq = first_bound_sq;
    for (const std::size_t i : missed)
      neighbours.answer(i, c, 2, bound_sq, mean_distance, done);
  }
}

} // namespace

namespace detail {

void
meanNeighbourDistances(const std::vector<float>& xyz,
                       const std::vector<char>& queried,
                       int mean_k,
                       std::vector<float>& mean_distance)
{
  PackedPoints packed{xyz};
  const std::size_t n_packed = packed.kdtree_get_point_count();
  using Tree = nanoflann::KDTreeSingleIndexAdaptor<
    nanoflann::L2_Simple_Adaptor<float, PackedPoints>, PackedPoints, 3, std::uint32_t>;
  const Tree tree(3, packed, nanoflann::KDTreeSingleIndexAdaptorParams(TREE_LEAF_SIZE));

  // One more neighbour than mean_k: the query point is its own nearest neighbour.
  const auto k = static_cast<std::size_t>(mean_k) + 1;
  mean_distance.assign(n_packed, 0.0f);
  std::vector<char> done(n_packed, 0);
  if (n_packed > k)
    meanDistancesInCells(packed.xyz, tree, queried, k, mean_k, mean_distance, done);

  // The points the cells could not answer exactly, from the tree, in its leaf order
  // (consecutive queries visit the same nodes).
  std::vector<std::uint32_t> nn_indices(k);
  std::vector<float> nn_dists(k);
  for (const auto j : tree.vAcc) {
    if (!queried[j] || done[j])
      continue;
    nanoflann::KNNResultSet<float, std::uint32_t> result(k);
    result.init(nn_indices.data(), nn_dists.data());
    tree.findNeighbors(result, &packed.xyz[3 * j], nanoflann::SearchParams());
    const std::size_t found = result.size();
    double dist_sum = 0.0;
    for (std::size_t n = 1; n < found; ++n)
      dist_sum += std::sqrt(nn_dists[n]);
    mean_distance[j] = static_cast<float>(dist_sum / mean_k);
  }
}

} // namespace detail

const ParamDeclarations<FastStatisticalOutlierRemovalParams>&
fastStatisticalOutlierRemovalParamDeclarations()
{
  using P = FastStatisticalOutlierRemovalParams;
  namespace ranges = fast_statistical_outlier_removal_ranges;
  static const ParamDeclarations<P> table = {
    declareInteger<P>(
      "mean_k", [](auto& p) -> auto& { return p.mean_k; }, ranges::MEAN_K, "",
      "Neighbours per point."),
    declareReal<P>(
      "stddev_mul_thresh", [](auto& p) -> auto& { return p.stddev_mul_thresh; },
      ranges::STDDEV_MUL_THRESH, "",
      "Standard-deviation multiplier of the distance threshold."),
  };
  return table;
}

} // namespace planar_grid

#ifndef PCL_NO_PRECOMPILE
#include <planar_grid/filters/impl/fast_statistical_outlier_removal.hpp>
#include <planar_grid/point_types.h>

#include <pcl/point_types.h>

// One explicit instantiation per point type of the CMake list PLANAR_GRID_POINT_TYPES.
#define PLANAR_GRID_INSTANTIATE_FastStatisticalOutlierRemoval(T) \
  template class planar_grid::FastStatisticalOutlierRemoval<T>;
PLANAR_GRID_INSTANTIATE(FastStatisticalOutlierRemoval, PLANAR_GRID_POINT_TYPES)
#endif // PCL_NO_PRECOMPILE
