// SPDX-License-Identifier: BSD-3-Clause
#pragma once

#include <cmath>

namespace planar_grid {

/** \brief Log-odds of a probability, log(p / (1 - p)) (OctoMap's logodds()).
 * \param[in] probability in (0, 1)
 * \return the log-odds (dimensionless); +-inf for 1 and 0
 * \ingroup core */
inline double
toLogOdds(double probability)
{
  return std::log(probability / (1.0 - probability));
}

/** \brief Probability of a log-odds value, 1 / (1 + exp(-l)) (OctoMap's probability()).
 * \param[in] log_odds the log-odds
 * \return the probability in [0, 1]
 * \ingroup core */
inline double
toProbability(double log_odds)
{
  return 1.0 / (1.0 + std::exp(-log_odds));
}

} // namespace planar_grid
