// SPDX-License-Identifier: BSD-3-Clause
#pragma once

#include <cmath>
#include <iomanip>
#include <limits>
#include <sstream>
#include <string>

namespace planar_grid {

/** \brief The valid range of one numeric parameter: an interval whose ends are each
 * open or closed, in the parameter's unit. A class declares the range of each of its
 * parameters once; its checkParameters() and the pipeline's stage table (the strict
 * configuration parser and `--list-stages`) both read that declaration, so that a value
 * one refuses the other refuses too. NaN and infinities are never contained; an
 * unbounded end is written with ParamRange::UNBOUNDED. \ingroup core */
struct ParamRange {
  /** \brief The value of an end that has no bound (use it open). */
  static constexpr double UNBOUNDED = std::numeric_limits<double>::infinity();

  /** \brief Lower end, in the parameter's unit (-UNBOUNDED for none). */
  double min{0.0};
  /** \brief Upper end, in the parameter's unit (UNBOUNDED for none). */
  double max{0.0};
  /** \brief True when the lower end itself is not in the range ("(0, ..."). */
  bool min_open{false};
  /** \brief True when the upper end itself is not in the range ("..., 1)"). */
  bool max_open{false};

  /** \brief The closed range [min, max].
   * \param[in] min lower end \param[in] max upper end
   * \return the range */
  static constexpr ParamRange closed(double min, double max)
  {
    return {min, max, false, false};
  }
  /** \brief The range (min, max], open below.
   * \param[in] min lower end, excluded \param[in] max upper end
   * \return the range */
  static constexpr ParamRange openMin(double min, double max)
  {
    return {min, max, true, false};
  }
  /** \brief The range [min, max), open above.
   * \param[in] min lower end \param[in] max upper end, excluded
   * \return the range */
  static constexpr ParamRange openMax(double min, double max)
  {
    return {min, max, false, true};
  }
  /** \brief The open range (min, max).
   * \param[in] min lower end, excluded \param[in] max upper end, excluded
   * \return the range */
  static constexpr ParamRange open(double min, double max)
  {
    return {min, max, true, true};
  }

  /** \brief Whether \a value lies in the range (false for NaN and infinities).
   * \param[in] value the value, in the parameter's unit
   * \return true when it is finite and within both ends */
  constexpr bool contains(double value) const
  {
    // value - value is 0 only for a finite value (NaN for NaN and infinities).
    return value - value == 0.0 && (min_open ? value > min : value >= min)
           && (max_open ? value < max : value <= max);
  }
};

/** \brief A number as ranges, defaults and messages write it: up to 10 significant
 * digits (0.1, 40, 1e-06, 100000000), "inf" for an unbounded end.
 * \param[in] value the number
 * \return its text
 * \ingroup core */
inline std::string
formatParamNumber(double value)
{
  std::ostringstream out;
  out << std::setprecision(10) << value;
  return out.str();
}

/** \brief A range written as an interval with its unit: "(0, 10] m", "[3, 100000000]",
 * "[0, inf) m".
 * \param[in] range the range
 * \param[in] unit the unit in words ("" for none)
 * \return the interval, then a space and the unit when there is one
 * \ingroup core */
inline std::string
formatParamRange(const ParamRange& range, const std::string& unit = "")
{
  return (range.min_open ? "(" : "[") + formatParamNumber(range.min) + ", "
         + formatParamNumber(range.max) + (range.max_open ? ")" : "]")
         + (unit.empty() ? "" : " " + unit);
}

/** \brief The message of a parameter outside its range, "<name> must be in <range>"
 * ("distance_threshold must be in (0, 1] m").
 * \param[in] name the parameter's name
 * \param[in] range its range
 * \param[in] unit the unit in words ("" for none)
 * \return the message
 * \ingroup core */
inline std::string
paramRangeMessage(const std::string& name,
                  const ParamRange& range,
                  const std::string& unit = "")
{
  return name + " must be in " + formatParamRange(range, unit);
}

} // namespace planar_grid
