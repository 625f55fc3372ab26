// SPDX-License-Identifier: BSD-3-Clause
#include <planar_grid/core/exceptions.h>
#include <planar_grid/pipeline/yaml_reader.h>

#include <yaml-cpp/depthguard.h>
#include <yaml-cpp/yaml.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <set>
#include <sstream>

namespace planar_grid {

namespace fs = std::filesystem;

namespace {

/** The deepest nesting of maps and lists accepted (the configuration schemas need 4).
 */
constexpr std::size_t MAX_NESTING = 32;
/** The most nodes a document may hold, aliases counted at each use. */
constexpr std::size_t MAX_NODES = 1000000;
/** The largest configuration file read, bytes: a generated list of 19,000 stages is
 * about 1 MB. */
constexpr std::uintmax_t MAX_CONFIG_BYTES = 16u << 20;

/** A tab in a line's indentation (before its first other character, comments and
 * blank lines aside) is an error at its line:col: YAML indents with spaces only, and
 * yaml-cpp reports such a file as "end of map not found" somewhere after the tab. */
void
checkIndentation(const std::string& text, const std::string& source)
{
  int line = 1;
  for (std::size_t start = 0; start < text.size();) {
    std::size_t end = text.find('\n', start);
    if (end == std::string::npos)
      end = text.size();
    const std::size_t first = text.find_first_not_of(" \t\r", start);
    if (first < end && text[first] != '#') {
      const std::size_t tab = text.find('\t', start);
      if (tab < first)
        throw ConfigError(source, line, static_cast<int>(tab - start) + 1,
                          "tab character in the indentation: YAML indents with "
                          "spaces, never tabs");
    }
    start = end + 1;
    ++line;
  }
}

/** Refuses a document nested deeper than MAX_NESTING, or one whose anchors and aliases
 * expand to more than MAX_NODES nodes, at the node's line:col (the configuration
 * schemas are at most four levels deep). */
void
checkNesting(const YAML::Node& node,
             std::size_t depth,
             std::size_t& visited,
             const std::string& source)
{
  const auto fail = [&](const std::string& message) {
    const YAML::Mark mark = node.Mark();
    throw ConfigError(source, mark.is_null() ? 0 : mark.line + 1,
                      mark.is_null() ? 0 : mark.column + 1, message);
  };
  if (depth > MAX_NESTING)
    fail("the YAML nests more than " + std::to_string(MAX_NESTING)
         + " levels deep here (at most " + std::to_string(MAX_NESTING)
         + " are accepted; the configuration schemas need 4)");
  if (++visited > MAX_NODES)
    fail("the YAML holds more than " + std::to_string(MAX_NODES)
         + " nodes (counting each use of an alias); a configuration file has a few "
           "hundred");
  if (node.IsSequence())
    for (const auto& item : node)
      checkNesting(item, depth + 1, visited, source);
  else if (node.IsMap())
    for (const auto& item : node) {
      checkNesting(item.first, depth + 1, visited, source);
      checkNesting(item.second, depth + 1, visited, source);
    }
}

} // namespace

std::string
readConfigFile(const std::string& path)
{
  // A device such as /dev/zero never ends, and a configuration of gigabytes is not
  // one: both would be read whole into memory before the YAML parser sees them.
  std::error_code ec;
  if (fs::exists(path, ec)) {
    if (!fs::is_regular_file(path, ec))
      throw IOError(path
                    + ": not a regular file (a device, pipe or folder); the "
                      "configuration is read from a YAML file");
    const std::uintmax_t size = fs::file_size(path, ec);
    if (!ec && size > MAX_CONFIG_BYTES)
      throw IOError(path + ": the configuration file is " + std::to_string(size)
                    + " bytes; at most " + std::to_string(MAX_CONFIG_BYTES)
                    + " are read (a pipeline of 256 stages takes a few kilobytes)");
  }
  std::ifstream in(path, std::ios::binary);
  if (!in)
    throw IOError(path + ": cannot open the configuration file");
  std::ostringstream text;
  text << in.rdbuf();
  return text.str();
}

YAML::Node
loadYamlDocument(const std::string& yaml_text, const std::string& source_name)
{
  checkIndentation(yaml_text, source_name);
  YAML::Node root;
  try {
    root = YAML::Load(yaml_text);
  } catch (const YAML::DeepRecursion& e) {
    // yaml-cpp's own guard against a stack overflow says "bad file".
    throw ConfigError(source_name, e.mark.line + 1, e.mark.column + 1,
                      "the YAML nests more than " + std::to_string(e.depth())
                        + " levels deep here (at most " + std::to_string(MAX_NESTING)
                        + " are accepted; the configuration schemas need 4)");
  } catch (const YAML::ParserException& e) {
    throw ConfigError(source_name, e.mark.line + 1, e.mark.column + 1, e.msg);
  }
  std::size_t visited = 0;
  checkNesting(root, 0, visited, source_name);
  return root;
}

YamlReader::YamlReader(std::string file, std::string base_folder) :
    file_(std::move(file)), base_folder_(std::move(base_folder))
{}

void
YamlReader::fail(const YAML::Node& node, const std::string& message) const
{
  const YAML::Mark mark = node.Mark();
  throw ConfigError(file_, mark.is_null() ? 0 : mark.line + 1,
                    mark.is_null() ? 0 : mark.column + 1, message);
}

void
YamlReader::requireMap(const YAML::Node& node, const std::string& what) const
{
  if (!node.IsMap())
    fail(node, what + " must be a map of key: value");
}

void
YamlReader::forEachKey(
  const YAML::Node& node,
  const std::string& what,
  const std::function<void(const std::string&, const YAML::Node&, const YAML::Node&)>&
    visit) const
{
  requireMap(node, what);
  std::set<std::string> seen;
  for (const auto& item : node) {
    if (!item.first.IsScalar())
      fail(item.first, "a key in " + what + " must be a plain name");
    const std::string key = item.first.as<std::string>();
    if (!seen.insert(key).second)
      fail(item.first, "key '" + key + "' is given twice in " + what);
    visit(key, item.first, item.second);
  }
}

void
YamlReader::checkKeys(const YAML::Node& node,
                      const std::vector<std::string>& allowed,
                      const std::string& what) const
{
  forEachKey(
    node, what,
    [&](const std::string& key, const YAML::Node& key_node, const YAML::Node&) {
      if (std::find(allowed.begin(), allowed.end(), key) != allowed.end())
        return;
      std::string list;
      for (const auto& a : allowed)
        list += (list.empty() ? "" : ", ") + a;
      fail(key_node,
           "unknown key '" + key + "' in " + what + "; expected one of: " + list);
    });
}

std::string
YamlReader::string(const YAML::Node& parent,
                   const std::string& key,
                   const std::string& what) const
{
  const YAML::Node node = parent[key];
  if (!node)
    fail(parent, what + " needs the key '" + key + "'");
  if (!node.IsScalar())
    fail(node, what + "." + key + " must be a string");
  return node.as<std::string>();
}

std::string
YamlReader::optionalString(const YAML::Node& parent,
                           const std::string& key,
                           const std::string& fallback,
                           const std::string& what) const
{
  return parent[key] ? string(parent, key, what) : fallback;
}

long long
YamlReader::integerValue(const YAML::Node& node,
                         long long min,
                         long long max,
                         const std::string& what) const
{
  long long v = 0;
  try {
    if (!node.IsScalar())
      throw YAML::BadConversion(node.Mark());
    v = node.as<long long>();
  } catch (const YAML::BadConversion&) {
    fail(node, what + " must be an integer");
  }
  if (v < min || v > max)
    fail(node, what + " = " + std::to_string(v) + " is out of range ["
                 + std::to_string(min) + ", " + std::to_string(max) + "]");
  return v;
}

double
YamlReader::realValue(const YAML::Node& node,
                      double min,
                      double max,
                      const std::string& what) const
{
  return realValue(node, ParamRange::closed(min, max), "", what);
}

double
YamlReader::realValue(const YAML::Node& node,
                      const ParamRange& range,
                      const std::string& unit,
                      const std::string& what) const
{
  double v = 0.0;
  try {
    if (!node.IsScalar())
      throw YAML::BadConversion(node.Mark());
    v = node.as<double>();
  } catch (const YAML::BadConversion&) {
    fail(node, what + " must be a number");
  }
  if (!range.contains(v))
    fail(node, what + " = " + formatParamNumber(v) + " is out of range "
                 + formatParamRange(range, unit));
  return v;
}

int
YamlReader::integer(const YAML::Node& parent,
                    const std::string& key,
                    int fallback,
                    int min,
                    int max,
                    const std::string& what) const
{
  const YAML::Node node = parent[key];
  if (!node)
    return fallback;
  return static_cast<int>(integerValue(node, min, max, what + "." + key));
}

bool
YamlReader::boolean(const YAML::Node& parent,
                    const std::string& key,
                    bool fallback,
                    const std::string& what) const
{
  const YAML::Node node = parent[key];
  if (!node)
    return fallback;
  bool v = false;
  try {
    if (!node.IsScalar())
      throw YAML::BadConversion(node.Mark());
    v = node.as<bool>();
  } catch (const YAML::BadConversion&) {
    fail(node, what + "." + key + " must be true or false");
  }
  return v;
}

double
YamlReader::real(const YAML::Node& parent,
                 const std::string& key,
                 double fallback,
                 double min,
                 double max,
                 const std::string& what) const
{
  const YAML::Node node = parent[key];
  if (!node)
    return fallback;
  return realValue(node, min, max, what + "." + key);
}

double
YamlReader::real(const YAML::Node& parent,
                 const std::string& key,
                 double fallback,
                 const ParamRange& range,
                 const std::string& unit,
                 const std::string& what) const
{
  const YAML::Node node = parent[key];
  if (!node)
    return fallback;
  return realValue(node, range, unit, what + "." + key);
}

std::string
YamlReader::path(const YAML::Node& parent,
                 const std::string& key,
                 const std::string& what) const
{
  return resolve(string(parent, key, what));
}

std::string
YamlReader::resolve(const std::string& text) const
{
  if (text.empty() || fs::path(text).is_absolute())
    return text;
  return (fs::path(base_folder_) / text).lexically_normal().string();
}

} // namespace planar_grid
