// SPDX-License-Identifier: BSD-3-Clause
// The procedural textures of SyntheticStereoScene's planes: multi-octave value noise,
// blobs and strokes from a deterministic random stream.
#include <algorithm>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <vector>

#include "synthetic_stereo_scene_impl.h"

namespace planar_grid {
namespace detail {

namespace {

/** \brief Texture content: value-noise octaves from 2 cm up (wavelength doubles). */
constexpr int NOISE_OCTAVES = 6;
constexpr double NOISE_FINEST_WAVELENGTH_M = 0.02;
/** \brief Texture content: blobs and strokes per square metre. */
constexpr double BLOBS_PER_M2 = 10.0;
constexpr double STROKES_PER_M2 = 4.0;
/** \brief Texture grey levels: mean and standard deviation, clamped to [10, 245]. */
constexpr double TEXTURE_MEAN = 128.0;
constexpr double TEXTURE_STDDEV = 42.0;

/** \brief A hash as a double in [0, 1). */
double
unitInterval(std::uint64_t h)
{
  return static_cast<double>(h >> 11) * 0x1.0p-53;
}

/** \brief A tiny deterministic random stream (SplitMix64). */
class Random {
public:
  explicit Random(std::uint64_t seed) : state_(seed) {}
  /** \brief Uniform in [lo, hi). */
  double uniform(double lo, double hi)
  {
    state_ += 0x9E3779B97F4A7C15ULL;
    return lo + (hi - lo) * unitInterval(mix(state_));
  }
  /** \brief -1 or +1. */
  double sign() { return uniform(0.0, 1.0) < 0.5 ? -1.0 : 1.0; }

private:
  std::uint64_t state_;
};

/** \brief Value noise: a random value in [-1, 1] at each lattice point of spacing
 * \a wavelength_m, smoothstep-interpolated between them. */
double
valueNoise(std::uint64_t seed, int octave, double u_m, double v_m, double wavelength_m)
{
  const double x = u_m / wavelength_m;
  const double y = v_m / wavelength_m;
  const double fx = std::floor(x), fy = std::floor(y);
  const auto ix = static_cast<std::int64_t>(fx), iy = static_cast<std::int64_t>(fy);
  const double tx = x - fx, ty = y - fy;
  const double sx = tx * tx * (3.0 - 2.0 * tx), sy = ty * ty * (3.0 - 2.0 * ty);
  const std::uint64_t base = mix(seed ^ mix(static_cast<std::uint64_t>(octave)));
  const auto lattice = [base](std::int64_t i, std::int64_t j) {
    const std::uint64_t h = mix(
      base ^ mix(static_cast<std::uint64_t>(i) ^ mix(static_cast<std::uint64_t>(j))));
    return 2.0 * unitInterval(h) - 1.0;
  };
  const double a = lattice(ix, iy), b = lattice(ix + 1, iy);
  const double c = lattice(ix, iy + 1), d = lattice(ix + 1, iy + 1);
  const double top = a + (b - a) * sx, bottom = c + (d - c) * sx;
  return top + (bottom - top) * sy;
}

} // namespace

/** \brief A grey texture of nu x nv texels covering width_m x height_m (texel (i, j)
 * centred at ((i + 0.5) width_m / nu, (j + 0.5) height_m / nv)), row-major with i
 * fastest: multi-octave value noise plus random blobs and strokes, normalised to
 * mean TEXTURE_MEAN and standard deviation TEXTURE_STDDEV. */
std::vector<unsigned char>
makeTexture(std::uint64_t seed, int nu, int nv, double width_m, double height_m)
{
  const double du = width_m / nu, dv = height_m / nv;
  const auto n = static_cast<std::size_t>(nu) * static_cast<std::size_t>(nv);
  std::vector<double> value(n, 0.0);
  // Noise: every octave with the same amplitude (a 1/f spectrum), so the surface has
  // texture at every distance (the mipmaps keep the coarse octaves far away).
  for (int j = 0; j < nv; ++j)
    for (int i = 0; i < nu; ++i) {
      const double u = (i + 0.5) * du, v = (j + 0.5) * dv;
      double sum = 0.0;
      for (int k = 0; k < NOISE_OCTAVES; ++k)
        sum +=
          valueNoise(seed, k, u, v, NOISE_FINEST_WAVELENGTH_M * std::ldexp(1.0, k));
      value[static_cast<std::size_t>(j) * static_cast<std::size_t>(nu)
            + static_cast<std::size_t>(i)] = sum;
    }
  // Unit standard deviation before the marks are added, so that their contrast is
  // the same on every surface.
  const auto normalise = [&value](double target_mean, double target_stddev) {
    double mean = 0.0;
    for (const double x : value)
      mean += x;
    mean /= static_cast<double>(value.size());
    double var = 0.0;
    for (const double x : value)
      var += (x - mean) * (x - mean);
    const double stddev = std::sqrt(var / static_cast<double>(value.size()));
    const double scale = stddev > 0.0 ? target_stddev / stddev : 0.0;
    for (double& x : value)
      x = target_mean + (x - mean) * scale;
  };
  normalise(0.0, 1.0);

  Random random(mix(seed ^ 0xB10B5ULL));
  const double area_m2 = width_m * height_m;
  // Adds weight(u, v) * amplitude over the texels of the box [u0, u1] x [v0, v1].
  const auto paint = [&](double u0, double u1, double v0, double v1, double amplitude,
                         const auto& weight) {
    const int i0 = std::max(0, static_cast<int>(std::floor(u0 / du)));
    const int i1 = std::min(nu - 1, static_cast<int>(std::ceil(u1 / du)));
    const int j0 = std::max(0, static_cast<int>(std::floor(v0 / dv)));
    const int j1 = std::min(nv - 1, static_cast<int>(std::ceil(v1 / dv)));
    for (int j = j0; j <= j1; ++j)
      for (int i = i0; i <= i1; ++i) {
        const double w = weight((i + 0.5) * du, (j + 0.5) * dv);
        if (w > 0.0)
          value[static_cast<std::size_t>(j) * static_cast<std::size_t>(nu)
                + static_cast<std::size_t>(i)] += amplitude * w;
      }
  };
  // Blobs: discs of 1.5-10 cm radius (log-uniform), flat with a soft rim.
  const auto blobs = static_cast<int>(std::lround(BLOBS_PER_M2 * area_m2));
  for (int b = 0; b < blobs; ++b) {
    const double cu = random.uniform(0.0, width_m), cv = random.uniform(0.0, height_m);
    const double r = 0.015 * std::exp(random.uniform(0.0, std::log(0.1 / 0.015)));
    const double amplitude = random.sign() * random.uniform(1.0, 2.0);
    paint(cu - r, cu + r, cv - r, cv + r, amplitude, [&](double u, double v) {
      const double dist = std::hypot(u - cu, v - cv);
      return std::clamp((r - dist) / (0.3 * r), 0.0, 1.0);
    });
  }
  // Strokes: segments 5-40 cm long, 0.8-3 cm wide, in any direction.
  const auto strokes = static_cast<int>(std::lround(STROKES_PER_M2 * area_m2));
  for (int s = 0; s < strokes; ++s) {
    const Eigen::Vector2d a(random.uniform(0.0, width_m),
                            random.uniform(0.0, height_m));
    const double length = random.uniform(0.05, 0.4);
    const double angle = random.uniform(0.0, 2.0 * M_PI);
    const Eigen::Vector2d b =
      a + length * Eigen::Vector2d(std::cos(angle), std::sin(angle));
    const double half_width = random.uniform(0.004, 0.015);
    const double amplitude = random.sign() * random.uniform(1.0, 2.0);
    const double reach = half_width + std::max(du, dv);
    paint(std::min(a.x(), b.x()) - reach, std::max(a.x(), b.x()) + reach,
          std::min(a.y(), b.y()) - reach, std::max(a.y(), b.y()) + reach, amplitude,
          [&](double u, double v) {
            const Eigen::Vector2d p(u, v);
            const Eigen::Vector2d ab = b - a;
            const double t = std::clamp((p - a).dot(ab) / ab.squaredNorm(), 0.0, 1.0);
            const double dist = (p - (a + t * ab)).norm();
            return std::clamp((reach - dist) / (reach - half_width), 0.0, 1.0);
          });
  }
  normalise(TEXTURE_MEAN, TEXTURE_STDDEV);
  std::vector<unsigned char> texels(n);
  for (std::size_t k = 0; k < n; ++k)
    texels[k] =
      static_cast<unsigned char>(std::lround(std::clamp(value[k], 10.0, 245.0)));
  return texels;
}

} // namespace detail
} // namespace planar_grid
