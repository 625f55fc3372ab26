// SPDX-License-Identifier: BSD-3-Clause
#pragma once

#include <planar_grid/core/param_range.h>

#include <functional>
#include <string>
#include <vector>

namespace YAML {
class Node;
} // namespace YAML

namespace planar_grid {

/** \brief The text of the configuration file \a path.
 * \throws planar_grid::IOError when it cannot be opened \ingroup pipeline */
std::string readConfigFile(const std::string& path);

/** \brief Parses a configuration document (a pipeline or an evaluation file) the one
 * strict way: a tab in a line's indentation, a syntax error, nesting deeper than 32
 * levels or more than a million nodes (aliases counted at each use) is an error at its
 * line:col, never a yaml-cpp exception.
 * \param[in] yaml_text the document
 * \param[in] source_name names it in errors (its file path)
 * \return the root node
 * \throws planar_grid::ConfigError \ingroup pipeline */
YAML::Node loadYamlDocument(const std::string& yaml_text,
                            const std::string& source_name);

/** \brief Strict access to a YAML configuration (yaml-cpp nodes): every error is a
 * planar_grid::ConfigError at the offending node's file:line:col saying what was
 * expected. Shared by the pipeline configuration, the stage parameter tables and the
 * evaluation configuration.
 *
 * Keys must be plain names, given once and known (checkKeys, forEachKey); values must
 * be scalars of the right type within their range. \ingroup pipeline */
class YamlReader {
public:
  /** \brief A reader of \a file; relative paths resolve against \a base_folder
   * (usually the file's folder; empty: the working directory).
   * \param[in] file the YAML file (or source name), for messages
   * \param[in] base_folder the folder relative paths start from */
  YamlReader(std::string file, std::string base_folder);

  /** \brief The file it reads. */
  const std::string& file() const { return file_; }

  /** \brief Throws ConfigError at \a node's position (line:col 0:0 when yaml-cpp has
   * none). */
  [[noreturn]] void fail(const YAML::Node& node, const std::string& message) const;

  /** \brief Throws unless \a node is a map. */
  void requireMap(const YAML::Node& node, const std::string& what) const;

  /** \brief Calls \a visit(key, key_node, value_node) for each entry of the map
   * \a node, after checking that the key is a plain name and not given twice (yaml-cpp
   * keeps both of two equal keys, and lookups find the first). */
  void forEachKey(
    const YAML::Node& node,
    const std::string& what,
    const std::function<void(const std::string&, const YAML::Node&, const YAML::Node&)>&
      visit) const;

  /** \brief Every key of the map \a node must be in \a allowed (plain, once). */
  void checkKeys(const YAML::Node& node,
                 const std::vector<std::string>& allowed,
                 const std::string& what) const;

  /** \brief The string value of parent[key]; the key is required. */
  std::string string(const YAML::Node& parent,
                     const std::string& key,
                     const std::string& what) const;

  /** \brief The string value of parent[key], or \a fallback when it is absent. */
  std::string optionalString(const YAML::Node& parent,
                             const std::string& key,
                             const std::string& fallback,
                             const std::string& what) const;

  /** \brief The integer value of parent[key] in [min, max], or \a fallback when it is
   * absent. */
  int integer(const YAML::Node& parent,
              const std::string& key,
              int fallback,
              int min,
              int max,
              const std::string& what) const;

  /** \brief The finite real value of parent[key] in [min, max], or \a fallback when it
   * is absent. */
  double real(const YAML::Node& parent,
              const std::string& key,
              double fallback,
              double min,
              double max,
              const std::string& what) const;
  /** \brief The real value of parent[key] within \a range (its unit \a unit, for
   * the message), or \a fallback when it is absent. */
  double real(const YAML::Node& parent,
              const std::string& key,
              double fallback,
              const ParamRange& range,
              const std::string& unit,
              const std::string& what) const;

  /** \brief The boolean value (true/false, yes/no, on/off) of parent[key], or
   * \a fallback when it is absent. */
  bool boolean(const YAML::Node& parent,
               const std::string& key,
               bool fallback,
               const std::string& what) const;

  /** \brief The integer value of \a node (a list entry, say) in [min, max]. */
  long long integerValue(const YAML::Node& node,
                         long long min,
                         long long max,
                         const std::string& what) const;

  /** \brief The finite real value of \a node in [min, max]. */
  double realValue(const YAML::Node& node,
                   double min,
                   double max,
                   const std::string& what) const;
  /** \brief The real value of \a node within \a range (its unit \a unit, for the
   * message). */
  double realValue(const YAML::Node& node,
                   const ParamRange& range,
                   const std::string& unit,
                   const std::string& what) const;

  /** \brief The path in parent[key] (required), resolved by resolve(). */
  std::string
  path(const YAML::Node& parent, const std::string& key, const std::string& what) const;

  /** \brief \a text resolved against the base folder when relative (empty stays
   * empty). */
  std::string resolve(const std::string& text) const;

private:
  std::string file_;
  std::string base_folder_;
};

} // namespace planar_grid
