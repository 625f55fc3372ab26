// SPDX-License-Identifier: BSD-3-Clause
#pragma once

#include <planar_grid/core/exceptions.h>
#include <planar_grid/core/param_range.h>

#include <functional>
#include <string>
#include <utility>
#include <variant>
#include <vector>

namespace planar_grid {

/** \brief How a parameter follows the map's minimum cell size r, for tools that run one
 * configuration at several cell sizes (planar_grid_eval, paper Sec. IV-B).
 * \ingroup core */
enum class CellSizeScaling {
  /** Independent of the cell size. */
  NONE,
  /** A length that is the cell size (a voxel edge, a minimum cell, a thickness): set
   * to r, in meters. */
  CELL_SIZE,
  /** A count of points on a surface, given for 0.1 m cells: scaled by (0.1 / r)^2 (the
   * same area holds that many fewer voxels), at least 10. */
  POINTS_PER_AREA,
  /** A length given for 0.1 m cells that spans several of them (a neighbourhood
   * radius): scaled by r / 0.1, in meters. */
  LENGTH
};

/** \brief A parameter's value: a real number, an integer, a flag, or a choice's name.
 * \ingroup core */
using ParamValue = std::variant<double, int, bool, std::string>;

/** \brief The one declaration of one member of an algorithm's \a Params: its key (with
 * the unit as suffix), value type, range, unit, meaning, and how to read and write it.
 *
 * An algorithm declares its parameters once, as a ParamDeclarations table next to its
 * Params struct. The default is the member's initializer (read from a
 * default-constructed Params); everything else that lists the parameters is made from
 * the table: the pipeline stage's parameter list, its strict parsing into Params and
 * the echo of the effective values (planar_grid::paramSpecs(), assignParams(),
 * reportParams()), the generated stage reference, and the Python keyword arguments.
 * \tparam Params the algorithm's parameter struct (default-constructible)
 * \ingroup core */
template <typename Params> struct ParamDeclaration {
  /** \brief The value type: a real number, an integer, a flag or one of choices. */
  enum class Type { DOUBLE, INT, BOOL, CHOICE };

  /** \brief Key, snake_case, ending in its unit (_m, _px, _rad, ...) when it has one.
   */
  std::string key;
  /** \brief Value type. */
  Type type{Type::DOUBLE};
  /** \brief Valid range of a DOUBLE or INT, in the parameter's unit. */
  ParamRange range;
  /** \brief Unit in words ("m", "px", "probability", "" for counts and flags). */
  std::string unit;
  /** \brief One or a few sentences on what it does. */
  std::string description;
  /** \brief Allowed names of a CHOICE, in the order documented. */
  std::vector<std::string> choices;
  /** \brief How the parameter follows the cell size (NONE by default). */
  CellSizeScaling cell_size_scaling{CellSizeScaling::NONE};
  /** \brief Reads the member: a double, int, bool or (CHOICE) std::string. */
  std::function<ParamValue(const Params&)> get;
  /** \brief Writes the member from a value of the declared type.
   * \throws planar_grid::Exception for a choice name that is not one of choices (from
   * the choice's parser), or std::bad_variant_access for another value type */
  std::function<void(Params&, const ParamValue&)> set;

  /** \brief This declaration, marked as following the cell size.
   * \param[in] scaling how it follows
   * \return a copy with cell_size_scaling = \a scaling */
  ParamDeclaration
  scalesWithCellSize(CellSizeScaling scaling = CellSizeScaling::CELL_SIZE) const
  {
    ParamDeclaration declaration = *this;
    declaration.cell_size_scaling = scaling;
    return declaration;
  }
};

/** \brief An algorithm's parameter table: one ParamDeclaration per member of its
 * Params, in the order they are documented. \ingroup core */
template <typename Params>
using ParamDeclarations = std::vector<ParamDeclaration<Params>>;

namespace detail {

/** \brief A declaration of the member that \a access returns a reference to; \a access
 * is a generic lambda, `[](auto& p) -> auto& { return p.member; }`, called with a
 * const and a non-const Params. */
template <typename Params, typename Value, typename Access>
ParamDeclaration<Params>
declareMember(typename ParamDeclaration<Params>::Type type,
              std::string key,
              Access access,
              const ParamRange& range,
              std::string unit,
              std::string description)
{
  ParamDeclaration<Params> declaration;
  declaration.key = std::move(key);
  declaration.type = type;
  declaration.range = range;
  declaration.unit = std::move(unit);
  declaration.description = std::move(description);
  declaration.get = [access](const Params& params) {
    return ParamValue(static_cast<Value>(access(params)));
  };
  declaration.set = [access](Params& params, const ParamValue& value) {
    access(params) = std::get<Value>(value);
  };
  return declaration;
}

} // namespace detail

/** \brief Declares a real-valued member.
 * \param[in] key key ending in its unit
 * \param[in] access `[](auto& p) -> auto& { return p.member; }`
 * \param[in] range the values the algorithm accepts, in the unit
 * \param[in] unit the unit in words
 * \param[in] description what it does
 * \return the declaration \ingroup core */
template <typename Params, typename Access>
ParamDeclaration<Params>
declareReal(std::string key,
            Access access,
            const ParamRange& range,
            std::string unit,
            std::string description)
{
  return detail::declareMember<Params, double>(ParamDeclaration<Params>::Type::DOUBLE,
                                               std::move(key), access, range,
                                               std::move(unit), std::move(description));
}

/** \brief Declares an integer member (see declareReal()). \ingroup core */
template <typename Params, typename Access>
ParamDeclaration<Params>
declareInteger(std::string key,
               Access access,
               const ParamRange& range,
               std::string unit,
               std::string description)
{
  return detail::declareMember<Params, int>(ParamDeclaration<Params>::Type::INT,
                                            std::move(key), access, range,
                                            std::move(unit), std::move(description));
}

/** \brief Declares a boolean member.
 * \param[in] key key
 * \param[in] access `[](auto& p) -> auto& { return p.member; }`
 * \param[in] description what it does
 * \return the declaration \ingroup core */
template <typename Params, typename Access>
ParamDeclaration<Params>
declareFlag(std::string key, Access access, std::string description)
{
  return detail::declareMember<Params, bool>(ParamDeclaration<Params>::Type::BOOL,
                                             std::move(key), access, ParamRange{}, "",
                                             std::move(description));
}

/** \brief Declares a member of an enumeration that is written as one of \a choices.
 * \param[in] key key
 * \param[in] access `[](auto& p) -> auto& { return p.member; }`
 * \param[in] choices the names, in the order documented
 * \param[in] to_name the name of a value (one of \a choices)
 * \param[in] from_name the value of a name; throws planar_grid::Exception for a name
 * that is none
 * \param[in] description what it does
 * \return the declaration \ingroup core */
template <typename Params, typename Access, typename ToName, typename FromName>
ParamDeclaration<Params>
declareChoice(std::string key,
              Access access,
              std::vector<std::string> choices,
              ToName to_name,
              FromName from_name,
              std::string description)
{
  ParamDeclaration<Params> declaration;
  declaration.key = std::move(key);
  declaration.type = ParamDeclaration<Params>::Type::CHOICE;
  declaration.description = std::move(description);
  declaration.choices = std::move(choices);
  declaration.get = [access, to_name](const Params& params) {
    return ParamValue(std::string(to_name(access(params))));
  };
  declaration.set = [access, from_name](Params& params, const ParamValue& value) {
    access(params) = from_name(std::get<std::string>(value));
  };
  return declaration;
}

/** \brief Declares a member of an enumeration (or any value type) written as one of
 * the names of \a names, the one table of both directions: the choices are its names
 * in order, a value's name is the first entry holding it, and a name that is none
 * throws planar_grid::Exception ("Unknown KEY 'NAME' (a, b, c)").
 * \param[in] key key
 * \param[in] access `[](auto& p) -> auto& { return p.member; }`
 * \param[in] names each name with its value, in the order documented
 * \param[in] description what it does
 * \return the declaration \ingroup core */
template <typename Params, typename Value, typename Access>
ParamDeclaration<Params>
declareNamedChoice(std::string key,
                   Access access,
                   std::vector<std::pair<std::string, Value>> names,
                   std::string description)
{
  std::vector<std::string> choices;
  std::string listed;
  for (const auto& entry : names) {
    listed += (choices.empty() ? "" : ", ") + entry.first;
    choices.push_back(entry.first);
  }
  const auto to_name = [names](const Value& value) -> const std::string& {
    for (const auto& entry : names)
      if (entry.second == value)
        return entry.first;
    return names.front().first;
  };
  const auto from_name = [names, key, listed](const std::string& name) {
    for (const auto& entry : names)
      if (entry.first == name)
        return entry.second;
    throw Exception("Unknown " + key + " '" + name + "' (" + listed + ")");
  };
  return declareChoice<Params>(std::move(key), access, std::move(choices), to_name,
                               from_name, std::move(description));
}

/** \brief The first member of \a params outside its declared range, as
 * paramRangeMessage() writes it with the value ("terrain_cell_m must be in
 * [0.05, 100] m, got 0"); empty when every number lies in its range. Choices and
 * flags have no range to check.
 * \param[in] table the declarations
 * \param[in] params the values
 * \return the message, or "" \ingroup core */
template <typename Params>
std::string
checkDeclaredRanges(const ParamDeclarations<Params>& table, const Params& params)
{
  using Type = typename ParamDeclaration<Params>::Type;
  for (const auto& declaration : table) {
    if (declaration.type != Type::DOUBLE && declaration.type != Type::INT)
      continue;
    const ParamValue value = declaration.get(params);
    const double number = declaration.type == Type::DOUBLE
                            ? std::get<double>(value)
                            : static_cast<double>(std::get<int>(value));
    if (!declaration.range.contains(number))
      return paramRangeMessage(declaration.key, declaration.range, declaration.unit)
             + ", got " + formatParamNumber(number);
  }
  return "";
}

} // namespace planar_grid
