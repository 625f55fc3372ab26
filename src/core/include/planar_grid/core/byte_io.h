// SPDX-License-Identifier: BSD-3-Clause
#pragma once

#include <planar_grid/core/exceptions.h>

#include <Eigen/Geometry>

#include <boost/crc.hpp>
#include <cstddef>
#include <cstdint>
#include <cstring>
#include <string>
#include <type_traits>
#include <vector>

#if defined(__BYTE_ORDER__) && __BYTE_ORDER__ != __ORDER_LITTLE_ENDIAN__
#error "planar_grid's binary sections assume a little-endian host"
#endif

namespace planar_grid {

/** \brief Appends little-endian values to a byte vector (the binary sections of the map
 * file and of pipeline checkpoints). \ingroup core */
class ByteWriter {
public:
  /** \param[out] bytes the vector appended to (kept by reference) */
  explicit ByteWriter(std::vector<std::uint8_t>& bytes) : bytes_(bytes) {}

  /** \brief Appends one arithmetic value (its in-memory bytes; the host is
   * little-endian, checked at compile time). */
  template <typename T> void put(T value)
  {
    static_assert(std::is_arithmetic<T>::value, "arithmetic only");
    std::uint8_t raw[sizeof(T)];
    std::memcpy(raw, &value, sizeof(T));
    bytes_.insert(bytes_.end(), raw, raw + sizeof(T));
  }

  /** \brief Appends a u64 length, then the bytes. */
  void putBytes(const void* data, std::size_t size)
  {
    put(static_cast<std::uint64_t>(size));
    const auto* p = static_cast<const std::uint8_t*>(data);
    bytes_.insert(bytes_.end(), p, p + size);
  }

  /** \brief Appends a u64 length, then the characters. */
  void putString(const std::string& text) { putBytes(text.data(), text.size()); }

  /** \brief Appends a u64 count, then the values. */
  template <typename T> void putVector(const std::vector<T>& values)
  {
    static_assert(std::is_arithmetic<T>::value, "arithmetic only");
    putBytes(values.data(), values.size() * sizeof(T));
  }

private:
  std::vector<std::uint8_t>& bytes_;
};

/** \brief Reads what ByteWriter wrote, bounds-checked: reading past the end, or a count
 * larger than the bytes left, throws planar_grid::IOError naming \a what and the byte
 * offset (nothing is allocated from an unchecked count). \ingroup core */
class ByteReader {
public:
  /** \param[in] data, size the bytes (not copied; must outlive the reader)
   * \param[in] what names the data in error messages (e.g. "checkpoint file x.pgck") */
  ByteReader(const std::uint8_t* data, std::size_t size, std::string what) :
      data_(data), size_(size), what_(std::move(what))
  {}

  /** \brief Reads one arithmetic value. \throws planar_grid::IOError when truncated */
  template <typename T> T get()
  {
    static_assert(std::is_arithmetic<T>::value, "arithmetic only");
    require(sizeof(T));
    T value;
    std::memcpy(&value, data_ + pos_, sizeof(T));
    pos_ += sizeof(T);
    return value;
  }

  /** \brief Reads a u64 count of items of \a bytes_each bytes and checks that they fit
   * in the bytes left. \throws planar_grid::IOError naming \a item */
  std::size_t getCount(std::size_t bytes_each, const char* item)
  {
    const auto count = get<std::uint64_t>();
    if (bytes_each > 0 && count > remaining() / bytes_each)
      fail(std::string(item) + " count " + std::to_string(count)
           + " exceeds the remaining " + std::to_string(remaining()) + " bytes");
    return static_cast<std::size_t>(count);
  }

  /** \brief Reads a length-prefixed byte block; returns a pointer into the data.
   * \param[out] size its length
   * \param[in] item names the block in error messages */
  const std::uint8_t* getBytes(std::size_t& size, const char* item)
  {
    size = getCount(1, item);
    const std::uint8_t* p = data_ + pos_;
    pos_ += size;
    return p;
  }

  /** \brief Reads a length-prefixed string. */
  std::string getString(const char* item)
  {
    std::size_t size = 0;
    const auto* p = getBytes(size, item);
    return std::string(reinterpret_cast<const char*>(p), size);
  }

  /** \brief Reads what putVector() wrote. */
  template <typename T> void getVector(std::vector<T>& values, const char* item)
  {
    static_assert(std::is_arithmetic<T>::value, "arithmetic only");
    std::size_t size = 0;
    const auto* p = getBytes(size, item);
    if (size % sizeof(T) != 0)
      fail(std::string(item) + ": " + std::to_string(size)
           + " bytes is not a whole number of values");
    values.resize(size / sizeof(T));
    if (size > 0)
      std::memcpy(values.data(), p, size);
  }

  /** \brief Bytes not read yet. */
  std::size_t remaining() const { return size_ - pos_; }
  /** \brief Bytes read so far. */
  std::size_t position() const { return pos_; }

  /** \brief Throws planar_grid::IOError "<what>: <message> (at byte N)". */
  [[noreturn]] void fail(const std::string& message) const
  {
    throw IOError(what_ + ": " + message + " (at byte " + std::to_string(pos_) + ")");
  }

private:
  void require(std::size_t n) const
  {
    if (remaining() < n)
      fail("truncated: " + std::to_string(n) + " more bytes expected, "
           + std::to_string(remaining()) + " left");
  }

  const std::uint8_t* data_;
  std::size_t size_;
  std::size_t pos_{0};
  std::string what_;
};

/** \brief CRC-32 (IEEE 802.3, boost::crc_32_type) of \a size bytes: the checksum of the
 * map file and of pipeline checkpoints. \ingroup core */
inline std::uint32_t
crc32(const void* data, std::size_t size)
{
  boost::crc_32_type crc;
  crc.process_bytes(data, size);
  return crc.checksum();
}

/** \brief Appends the 3x4 upper part of a rigid transform, row by row, as f64
 * (meters). \ingroup core */
inline void
putPose(ByteWriter& w, const Eigen::Isometry3d& pose)
{
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 4; ++c)
      w.put(pose.matrix()(r, c));
}

/** \brief Reads what putPose() wrote. \throws planar_grid::IOError when truncated or
 * not finite */
inline Eigen::Isometry3d
getPose(ByteReader& r)
{
  Eigen::Isometry3d pose = Eigen::Isometry3d::Identity();
  for (int row = 0; row < 3; ++row)
    for (int c = 0; c < 4; ++c)
      pose.matrix()(row, c) = r.get<double>();
  if (!pose.matrix().allFinite())
    r.fail("non-finite pose");
  return pose;
}

} // namespace planar_grid
