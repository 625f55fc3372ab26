// SPDX-License-Identifier: BSD-3-Clause
#pragma once

#include <pcl/point_cloud.h>
#include <pcl/point_types.h>

#include <Eigen/Geometry>

#include <cstdint>
#include <string>
#include <vector>

namespace pcl {
struct PCLPointCloud2;
} // namespace pcl

namespace planar_grid {

/** \brief What checkPCDFile() read from a PCD header. \ingroup core */
struct PCDFileInfo {
  /** \brief The fields' names, in the file's order. */
  std::vector<std::string> fields;
  /** \brief WIDTH * HEIGHT: the points the header declares. */
  std::uint64_t points{0};
  /** \brief Bytes of one point (the fields' sizes times their counts). */
  std::uint64_t point_bytes{0};
  /** \brief 0 ascii, 1 binary, 2 binary_compressed (pcl::PCDReader's codes). */
  int data_type{0};
  /** \brief The VIEWPOINT translation (metres); w = 0. */
  Eigen::Vector4f sensor_origin{Eigen::Vector4f::Zero()};
  /** \brief The VIEWPOINT rotation (unit quaternion). */
  Eigen::Quaternionf sensor_orientation{Eigen::Quaternionf::Identity()};

  EIGEN_MAKE_ALIGNED_OPERATOR_NEW
};

/** \brief Checks that \a path is a PCD file pcl::PCDReader reads safely and completely,
 * before it is handed to pcl::io::loadPCDFile(). PCL's reader accepts a header without
 * any PCD keyword (an empty file, a text file, another format) and then reads past the
 * end of the file; it allocates what the header and the compressed sizes declare
 * before it looks at the data; it reads only the declared points of a file that holds
 * more; it takes an unparsable VIEWPOINT as the identity; and it gives the points of a
 * file without x, y, z fields a position of 0.
 *
 * The file must be a non-empty regular file whose first line that is not a comment is
 * a PCD keyword (VERSION or FIELDS), whose header pcl::PCDReader::readHeader() reads,
 * with at least one field of a known type and the fields x, y and z, and a VIEWPOINT
 * (if any) of seven finite numbers with a non-zero quaternion. Its data must hold
 * exactly the WIDTH * HEIGHT points the header declares: that many non-empty lines of
 * ASCII data; that many points of the fields' bytes for binary data (no whole point
 * more); for binary-compressed data, two sizes after the header whose compressed size
 * fits in the file, whose uncompressed size equals the points' bytes, and whose ratio
 * LZF can reach (at most 100: LZF codes at most 264 bytes in 3). \param[in] path the
 * file \return what the header declares \throws planar_grid::IOError naming the file
 * and the cause ("the file is empty (0 bytes)", "not a PCD file: ...", "is a planar
 * grid map (.pgmap) file", "truncated:
 * ...", "the compressed data ...", "the data hold N points, the header declares M",
 * "has no x, y, z fields", "VIEWPOINT ... is not a valid pose")
 * \ingroup core */
PCDFileInfo checkPCDFile(const std::string& path);

/** \brief Checks that pcl::fromPCLPointCloud2() can convert \a blob without reading
 * past its data: a point_step > 0, row_step >= width * point_step,
 * data of at least row_step * height bytes, and every field inside the point. For a
 * PCD file after checkPCDFile() and pcl::io::loadPCDFile() (PCL's ASCII reader can end
 * with fewer points than width * height say: it shortens the data and the width of a
 * malformed file but keeps the height) and for a sensor_msgs/PointCloud2 message.
 * \param[in] blob the cloud \param[in] where the file or message, for the message
 * \throws planar_grid::IOError naming \a where and the sizes
 * \ingroup core */
void checkPointCloudBlob(const pcl::PCLPointCloud2& blob, const std::string& where);

/** \brief Converts the fields \a names of \a blob that are not 32-bit floats (double,
 * int8 to int64, uint8 to uint64, bool) to 32-bit floats, in place, so that
 * pcl::fromPCLPointCloud2() reads them: PCL matches a point type's field by name *and*
 * datatype, and leaves a field whose datatype differs at 0 (a cloud with double x, y,
 * z would become one point at the origin). The other fields keep their bytes; the point
 * is repacked without padding. A double beyond the range of a float becomes an
 * infinite coordinate (a non-finite point, dropped as such). For a blob that passed
 * checkPointCloudBlob(). \param[in,out] blob the cloud \param[in] names the fields to
 * convert (e.g. x, y, z, intensity); absent ones are skipped \param[in] where the file
 * or message, for the message \throws planar_grid::IOError naming \a where and the
 * field when a field of \a names holds more than one value per point (COUNT > 1),
 * float or not, or a field to convert has a datatype PCL does not define
 * \ingroup core */
void convertFieldsToFloat(pcl::PCLPointCloud2& blob,
                          const std::vector<std::string>& names,
                          const std::string& where);

/** \brief Converts a PCL blob (a PCD file's or a PointCloud2 message's) to an
 * intensity cloud with the fields it has, so that PCL does not warn once per missing
 * field: an intensity field is kept, colour (rgb or rgba) becomes the grey intensity
 * (pcl::PointXYZRGBtoXYZI), bare x/y/z get intensity 0. The blob's x/y/z are checked by
 * the caller (checkPointCloudBlob(), convertFieldsToFloat()).
 * \param[in] blob the cloud
 * \param[out] cloud its points; empty for an empty blob
 * \ingroup core */
void intensityCloudFromBlob(const pcl::PCLPointCloud2& blob,
                            pcl::PointCloud<pcl::PointXYZI>& cloud);

} // namespace planar_grid
