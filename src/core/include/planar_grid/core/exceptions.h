// SPDX-License-Identifier: BSD-3-Clause
#pragma once

#include <stdexcept>
#include <string>

namespace planar_grid {

/** \brief Base of every exception PlanarGrid throws: programmer, configuration
 * and I/O errors, never data-dependent failures inside an algorithm.
 * \ingroup core */
class Exception : public std::runtime_error {
public:
  /** \brief An exception with the message \a what.
   * \param[in] what the full message, returned by what() */
  explicit Exception(const std::string& what) : std::runtime_error(what) {}
};

/** \brief A configuration error at a place in a YAML file.
 * what() reads "<file>:<line>:<col>: <message>" (line and column 1-based, as editors
 * count; omitted when unknown). \ingroup core */
class ConfigError : public Exception {
public:
  /** \param[in] file the YAML file ("" when parsed from a string)
   * \param[in] line 1-based line, or 0 when unknown
   * \param[in] column 1-based column, or 0 when unknown
   * \param[in] message what was wrong and what was expected */
  ConfigError(const std::string& file,
              int line,
              int column,
              const std::string& message);

  /** \brief The file named in the error ("" when none). */
  const std::string& file() const { return file_; }
  /** \brief 1-based line, 0 when unknown. */
  int line() const { return line_; }
  /** \brief 1-based column, 0 when unknown. */
  int column() const { return column_; }
  /** \brief What was wrong, without the location. */
  const std::string& message() const { return message_; }

private:
  std::string file_;
  int line_;
  int column_;
  std::string message_;
};

/** \brief A file that is missing, unreadable, truncated or malformed; what() names it.
 * \ingroup core */
class IOError : public Exception {
public:
  /** \brief An I/O error with the message \a what.
   * \param[in] what the message; it names the file and what was wrong with it */
  explicit IOError(const std::string& what) : Exception(what) {}
};

/** \brief An output that cannot be written, or that a run refuses to write before it
 * starts (a name that would overwrite an input, a folder in a file's place, a folder
 * that cannot be made); what() names the path and the cause. An IOError, so that
 * catching IOError catches it too. \ingroup core */
class OutputError : public IOError {
public:
  /** \brief An output error with the message \a what.
   * \param[in] what the message; it names the output and what was wrong with it */
  explicit OutputError(const std::string& what) : IOError(what) {}
};

/** \brief A run stopped on request (PipelineRunner::setStopFlag(), e.g. from a SIGINT
 * handler) between two frames; what() says after which frame. \ingroup core */
class Interrupted : public Exception {
public:
  /** \brief An interruption with the message \a what.
   * \param[in] what the message; it names the last frame that was mapped */
  explicit Interrupted(const std::string& what) : Exception(what) {}
};

} // namespace planar_grid
