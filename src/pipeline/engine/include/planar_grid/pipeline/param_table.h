// SPDX-License-Identifier: BSD-3-Clause
#pragma once

#include <planar_grid/core/exceptions.h>
#include <planar_grid/core/param_declaration.h>
#include <planar_grid/core/param_range.h>

#include <map>
#include <string>
#include <variant>
#include <vector>

namespace planar_grid {

/** \brief One parameter of a pipeline stage: its YAML key (with the unit as suffix),
 * type, default, range and meaning. The same table drives the strict parser and
 * `planar_grid_pipeline --list-stages`, so that the documentation cannot drift from
 * what is accepted. \ingroup pipeline */
struct ParamSpec {
  /** \brief The value type: a real number, an integer, a flag or one of choices. */
  enum class Type { DOUBLE, INT, BOOL, CHOICE };

  /** \brief YAML key, snake_case, ending in its unit (_m, _px, _rad, ...) when it has
   * one. */
  std::string key;
  /** \brief Value type. */
  Type type{Type::DOUBLE};
  /** \brief Default value, as text (a number, true/false, or one of choices). */
  std::string default_value;
  /** \brief Valid range of a DOUBLE or INT, in the parameter's unit: the class's
   * declared range where a class takes the parameter. */
  ParamRange range;
  /** \brief Unit in words ("m", "px", "probability", "" for counts and flags). */
  std::string unit;
  /** \brief One line on what it does. */
  std::string description;
  /** \brief Allowed values for CHOICE. */
  std::vector<std::string> choices;

  /** \brief How a parameter follows the map's minimum cell size r (the algorithms'
   * declarations use the same enumeration). */
  using CellSizeScaling = planar_grid::CellSizeScaling;
  /** \brief How the parameter follows the cell size (NONE by default). */
  CellSizeScaling cell_size_scaling{CellSizeScaling::NONE};

  /** \brief This specification, marked as following the cell size.
   * \param[in] scaling how it follows
   * \return a copy with cell_size_scaling = \a scaling */
  ParamSpec
  scalesWithCellSize(CellSizeScaling scaling = CellSizeScaling::CELL_SIZE) const
  {
    ParamSpec spec = *this;
    spec.cell_size_scaling = scaling;
    return spec;
  }

  /** \brief A real-valued parameter whose range is declared here (a parameter of
   * the pipeline only).
   * \param[in] key YAML key ending in its unit
   * \param[in] default_value the default, within [min, max]
   * \param[in] min inclusive lower bound
   * \param[in] max inclusive upper bound
   * \param[in] unit the unit in words
   * \param[in] description one line on what it does
   * \return the specification */
  static ParamSpec real(const std::string& key,
                        double default_value,
                        double min,
                        double max,
                        const std::string& unit,
                        const std::string& description);
  /** \brief A real-valued parameter that a library class takes, with the range the
   * class declares (and checks).
   * \param[in] key YAML key ending in its unit
   * \param[in] default_value the default, within \a range
   * \param[in] range the class's range
   * \param[in] unit the unit in words
   * \param[in] description one line on what it does
   * \return the specification */
  static ParamSpec real(const std::string& key,
                        double default_value,
                        const ParamRange& range,
                        const std::string& unit,
                        const std::string& description);
  /** \brief An integer parameter whose range is declared here (a parameter of the
   * pipeline only).
   * \param[in] key YAML key ending in its unit, if any
   * \param[in] default_value the default, within [min, max]
   * \param[in] min inclusive lower bound
   * \param[in] max inclusive upper bound
   * \param[in] unit the unit in words ("" for counts)
   * \param[in] description one line on what it does
   * \return the specification */
  static ParamSpec integer(const std::string& key,
                           int default_value,
                           int min,
                           int max,
                           const std::string& unit,
                           const std::string& description);
  /** \brief An integer parameter that a library class takes, with the range the class
   * declares (and checks).
   * \param[in] key YAML key ending in its unit, if any
   * \param[in] default_value the default, within \a range
   * \param[in] range the class's range
   * \param[in] unit the unit in words ("" for counts)
   * \param[in] description one line on what it does
   * \return the specification */
  static ParamSpec integer(const std::string& key,
                           int default_value,
                           const ParamRange& range,
                           const std::string& unit,
                           const std::string& description);
  /** \brief A boolean parameter.
   * \param[in] key YAML key
   * \param[in] default_value the default
   * \param[in] description one line on what it does
   * \return the specification */
  static ParamSpec
  flag(const std::string& key, bool default_value, const std::string& description);
  /** \brief A parameter that takes one of a list of names.
   * \param[in] key YAML key
   * \param[in] default_value the default, one of \a choices
   * \param[in] choices the allowed names
   * \param[in] description one line on what it does
   * \return the specification */
  static ParamSpec choice(const std::string& key,
                          const std::string& default_value,
                          const std::vector<std::string>& choices,
                          const std::string& description);
};

/** \brief The range of a DOUBLE or INT parameter as an interval ("(0, 1]", without the
 * unit); empty for other parameters. */
std::string formatParamRange(const ParamSpec& spec);

/** \brief What a parameter accepts, in words: "number", "integer", "true or false", or
 * "one of " and its choices joined by \a choice_separator. */
std::string formatParamType(const ParamSpec& spec, const std::string& choice_separator);

/** \brief The allowed names of a choice parameter joined by \a separator, in the
 * table's order ("sgbm|sgbm_3way|bm" with "|"); empty for other parameters. */
std::string formatParamChoices(const ParamSpec& spec, const std::string& separator);

/** \brief Parsed parameter values of one stage, every key of its table present (the
 * YAML value, or the default). Getters throw planar_grid::Exception for a key that is
 * not in the table (a programming error). \ingroup pipeline */
class ParamValues {
public:
  /** \brief Returns the value of a DOUBLE parameter.
   * \param[in] key the YAML key \return the value, in the key's unit */
  double getDouble(const std::string& key) const;
  /** \brief Returns the value of an INT parameter.
   * \param[in] key the YAML key \return the value */
  int getInt(const std::string& key) const;
  /** \brief Returns the value of a BOOL parameter.
   * \param[in] key the YAML key \return the value */
  bool getBool(const std::string& key) const;
  /** \brief Returns the value of a CHOICE parameter.
   * \param[in] key the YAML key \return one of the spec's choices */
  const std::string& getChoice(const std::string& key) const;

  /** \brief Stores a value (used by the parser). */
  void set(const std::string& key, std::variant<double, int, bool, std::string> value);

  /** \brief All values, by key (for echoing the effective parameters). */
  const std::map<std::string, std::variant<double, int, bool, std::string>>&
  values() const
  {
    return values_;
  }

  /** \brief The value of \a key as text. */
  std::string toString(const std::string& key) const;

private:
  std::map<std::string, std::variant<double, int, bool, std::string>> values_;
};

/** \brief The defaults of a table, as ParamValues. */
ParamValues defaultParams(const std::vector<ParamSpec>& specs);

/** \brief A human-readable description of a table: one line per key with type, default,
 * range (an interval, "(0, 10]") and unit. */
std::string describeParams(const std::vector<ParamSpec>& specs);

/** \brief Inserts \a spec into a stage's parameter list right after the key \a after,
 * so that a stage's own key stands beside the algorithm's key it goes with.
 * \param[in,out] specs the list
 * \param[in] after the key that \a spec follows
 * \param[in] spec the parameter
 * \throws planar_grid::Exception when \a specs has no key \a after (a programming
 * error) */
void insertParamSpec(std::vector<ParamSpec>& specs,
                     const std::string& after,
                     const ParamSpec& spec);

/** \brief A stage parameter from an algorithm's declaration, its default the value
 * of \a defaults.
 * \param[in] declaration the member's declaration
 * \param[in] defaults the algorithm's default parameters
 * \return the specification */
template <typename Params>
ParamSpec
toParamSpec(const ParamDeclaration<Params>& declaration, const Params& defaults)
{
  using Type = typename ParamDeclaration<Params>::Type;
  const ParamValue value = declaration.get(defaults);
  ParamSpec spec;
  switch (declaration.type) {
    case Type::DOUBLE:
      spec =
        ParamSpec::real(declaration.key, std::get<double>(value), declaration.range,
                        declaration.unit, declaration.description);
      break;
    case Type::INT:
      spec =
        ParamSpec::integer(declaration.key, std::get<int>(value), declaration.range,
                           declaration.unit, declaration.description);
      break;
    case Type::BOOL:
      spec = ParamSpec::flag(declaration.key, std::get<bool>(value),
                             declaration.description);
      break;
    case Type::CHOICE:
      spec = ParamSpec::choice(declaration.key, std::get<std::string>(value),
                               declaration.choices, declaration.description);
      break;
  }
  spec.cell_size_scaling = declaration.cell_size_scaling;
  return spec;
}

/** \brief A stage's parameter list from an algorithm's table, in the table's order,
 * with the defaults of \a defaults (a default-constructed Params: the class's
 * defaults are the pipeline's). */
template <typename Params>
std::vector<ParamSpec>
paramSpecs(const ParamDeclarations<Params>& table, const Params& defaults = Params{})
{
  std::vector<ParamSpec> specs;
  specs.reserve(table.size());
  for (const auto& declaration : table)
    specs.push_back(toParamSpec(declaration, defaults));
  return specs;
}

/** \brief Writes the parsed values of \a table's keys into \a params.
 * \throws planar_grid::Exception for a key of the table that \a values lacks (a
 * stage whose parameter list was not made from the table), or a choice name the
 * member's parser refuses */
template <typename Params>
void
assignParams(const ParamDeclarations<Params>& table,
             const ParamValues& values,
             Params& params)
{
  for (const auto& declaration : table) {
    const auto it = values.values().find(declaration.key);
    if (it == values.values().end())
      throw Exception("assignParams: no value for '" + declaration.key + "'");
    declaration.set(params, it->second);
  }
}

/** \brief Stores the values of \a params for \a table's keys in \a values (a stage's
 * echo of its effective parameters). */
template <typename Params>
void
reportParams(const ParamDeclarations<Params>& table,
             const Params& params,
             ParamValues& values)
{
  for (const auto& declaration : table)
    values.set(declaration.key, declaration.get(params));
}

} // namespace planar_grid
