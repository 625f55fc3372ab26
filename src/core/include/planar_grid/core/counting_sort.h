// SPDX-License-Identifier: BSD-3-Clause
// A stable counting sort of items by bucket, for the spatial buckets of key points.
#pragma once

#include <cstddef>
#include <vector>

namespace planar_grid {

/** \brief A stable counting sort of the items 0 .. bucket_of.size() - 1 by their
 * bucket: order[begin[b] .. begin[b + 1]) are the items of bucket b, in ascending
 * order, so that each bucket is one range of one array. An item whose bucket is
 * \a n_buckets or more is left out (a key point in an image's border, for example).
 * \param[in] bucket_of each item's bucket
 * \param[in] n_buckets the number of buckets
 * \param[out] begin n_buckets + 1 offsets into \a order
 * \param[out] order the items, bucket by bucket
 * \ingroup core */
template <typename Index>
void
countingSort(const std::vector<Index>& bucket_of,
             std::size_t n_buckets,
             std::vector<Index>& begin,
             std::vector<Index>& order)
{
  begin.assign(n_buckets + 1, 0);
  for (const Index b : bucket_of)
    if (static_cast<std::size_t>(b) < n_buckets)
      ++begin[static_cast<std::size_t>(b) + 1];
  for (std::size_t b = 0; b < n_buckets; ++b)
    begin[b + 1] += begin[b];
  order.resize(static_cast<std::size_t>(begin[n_buckets]));
  std::vector<Index> next(begin.begin(), begin.end() - 1);
  for (std::size_t i = 0; i < bucket_of.size(); ++i) {
    const auto b = static_cast<std::size_t>(bucket_of[i]);
    if (b < n_buckets)
      order[static_cast<std::size_t>(next[b]++)] = static_cast<Index>(i);
  }
}

} // namespace planar_grid
