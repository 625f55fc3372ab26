// SPDX-License-Identifier: BSD-3-Clause
#pragma once

#include <map>
#include <string>
#include <variant>
#include <vector>

namespace YAML {
class Node;
}

namespace planar_grid {

/** \brief One parameter of a pipeline stage: its YAML key (with the unit as suffix,
 * S21), type, default, range and meaning. The same table drives the strict parser and
 * `planar_grid_pipeline --list-stages` (S31). \ingroup pipeline */
struct ParamSpec {
  enum class Type { DOUBLE, INT, BOOL, CHOICE };

  /** \brief YAML key, snake_case, ending in its unit (_m, _px, _rad, ...) when it has
   * one. */
  std::string key;
  Type type{Type::DOUBLE};
  /** \brief Default value, as text (a number, true/false, or one of choices). */
  std::string default_value;
  /** \brief Inclusive range for DOUBLE and INT. */
  double min{0.0};
  double max{0.0};
  /** \brief Unit in words ("m", "px", "probability", "" for counts and flags). */
  std::string unit;
  /** \brief One line on what it does. */
  std::string description;
  /** \brief Allowed values for CHOICE. */
  std::vector<std::string> choices;

  static ParamSpec real(const std::string& key,
                        double default_value,
                        double min,
                        double max,
                        const std::string& unit,
                        const std::string& description);
  static ParamSpec integer(const std::string& key,
                           int default_value,
                           int min,
                           int max,
                           const std::string& unit,
                           const std::string& description);
  static ParamSpec
  flag(const std::string& key, bool default_value, const std::string& description);
  static ParamSpec choice(const std::string& key,
                          const std::string& default_value,
                          const std::vector<std::string>& choices,
                          const std::string& description);
};

/** \brief Parsed parameter values of one stage, every key of its table present (the
 * YAML value, or the default). Getters throw planar_grid::Exception for a key that is
 * not in the table (a programming error). \ingroup pipeline */
class ParamValues {
public:
  double getDouble(const std::string& key) const;
  int getInt(const std::string& key) const;
  bool getBool(const std::string& key) const;
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

/** \brief Parses a stage's `params:` map strictly against its table: an unknown key, a
 * value of the wrong type, or an out-of-range value is a planar_grid::ConfigError at
 * the value's file:line:col, saying what was expected. Missing keys take their
 * defaults. \param[in] node the `params` map (may be null/absent: all defaults)
 * \param[in] specs the stage's table
 * \param[in] file the YAML file, for messages
 * \param[in] stage_type the stage, for messages */
ParamValues parseParams(const YAML::Node& node,
                        const std::vector<ParamSpec>& specs,
                        const std::string& file,
                        const std::string& stage_type);

/** \brief The defaults of a table, as ParamValues. */
ParamValues defaultParams(const std::vector<ParamSpec>& specs);

/** \brief A human-readable description of a table: one line per key with type, default,
 * range and unit. */
std::string describeParams(const std::vector<ParamSpec>& specs);

} // namespace planar_grid
