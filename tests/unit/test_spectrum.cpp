// The residual in frequency: a line in white noise is found at its frequency with its amplitude, and
// is called coherent with the input when the input drives it and not when it comes from elsewhere; a
// residual of white noise at the sensor's level is called white.
#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include "diagnose/spectrum.hpp"

using namespace pamc;

namespace {

constexpr double kTs = 1e-3, kNoise = 0.005;
constexpr size_t kN = 60000;

std::vector<double> whiteNoise(unsigned seed, double std) {
  std::mt19937_64 g(seed);
  std::normal_distribution<double> n(0.0, std);
  std::vector<double> v(kN);
  for (auto& x : v) x = n(g);
  return v;
}

}  // namespace

TEST(Spectrum, WhiteNoiseAtTheSensorLevelIsWhite) {
  const auto e = whiteNoise(1, kNoise), u = whiteNoise(2, 1.0);
  const auto s = diagnose::residualSpectrum(e, u, kTs, kNoise);
  EXPECT_TRUE(s.peaks.empty());
  EXPECT_TRUE(s.white) << diagnose::describeSpectrum(s);
  EXPECT_NEAR(s.floor_psd / s.noise_psd, 1.0, 0.15);
  // Three times the noise is not at the noise.
  const auto loud = diagnose::residualSpectrum(whiteNoise(3, 3 * kNoise), u, kTs, kNoise);
  EXPECT_FALSE(loud.white);
}

TEST(Spectrum, ALineFromElsewhereIsFoundAndNotCoherent) {
  auto e = whiteNoise(4, kNoise);
  const auto u = whiteNoise(5, 1.0);
  for (size_t k = 0; k < kN; ++k) e[k] += 0.04 * std::sin(2 * M_PI * 11.3 * k * kTs + 0.5);
  const auto s = diagnose::residualSpectrum(e, u, kTs, kNoise);
  ASSERT_FALSE(s.peaks.empty());
  EXPECT_NEAR(s.peaks[0].hz, 11.3, 0.05);
  EXPECT_NEAR(s.peaks[0].amplitude, 0.04, 0.006);
  EXPECT_FALSE(s.peaks[0].coherent);
  EXPECT_FALSE(s.white);
}

TEST(Spectrum, ALineDrivenByTheInputIsCoherent) {
  // The input carries a 7 Hz component and the residual is that component through a gain and a lag.
  std::vector<double> u(kN), e = whiteNoise(6, kNoise);
  const auto un = whiteNoise(7, 0.2);
  for (size_t k = 0; k < kN; ++k) {
    u[k] = std::sin(2 * M_PI * 7.0 * k * kTs) + un[k];
    e[k] += 0.03 * std::sin(2 * M_PI * 7.0 * k * kTs - 0.8);
  }
  const auto s = diagnose::residualSpectrum(e, u, kTs, kNoise);
  ASSERT_FALSE(s.peaks.empty());
  EXPECT_NEAR(s.peaks[0].hz, 7.0, 0.05);
  EXPECT_TRUE(s.peaks[0].coherent) << s.peaks[0].coherence;
}

TEST(Spectrum, RecordsOfDifferentLengthAreAnError) {
  EXPECT_THROW(diagnose::residualSpectrum(std::vector<double>(2000), std::vector<double>(1999), kTs, kNoise),
               std::invalid_argument);
}
