// The identification inputs added for recording on a rig: the random-phase multisine and the APRBS -
// range, reproducibility, spectrum, holds - and the spec table parse() reads them from.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <complex>
#include <stdexcept>
#include <string>
#include <vector>

#include "control/trajectory.hpp"

using pamc::control::Trajectory;

namespace {

std::vector<double> sampled(const Trajectory& t, double seconds, double dt = 1e-3) {
  std::vector<double> x(static_cast<std::size_t>(std::llround(seconds / dt)));
  for (std::size_t i = 0; i < x.size(); ++i) x[i] = t.at(static_cast<double>(i) * dt);
  return x;
}

// |X_k|^2 of a plain DFT at bins 1..n/2 (an oracle that shares nothing with the table's construction).
std::vector<double> power(const std::vector<double>& x) {
  const std::size_t n = x.size();
  std::vector<double> p(n / 2 + 1, 0.0);
  for (std::size_t k = 1; k <= n / 2; ++k) {
    std::complex<double> s = 0.0;
    for (std::size_t i = 0; i < n; ++i) s += x[i] * std::polar(1.0, -2.0 * M_PI * double(k * i % n) / double(n));
    p[k] = std::norm(s);
  }
  return p;
}

}  // namespace

TEST(Trajectory, MultisineSpansExactlyItsRange) {
  const auto t = Trajectory::parse("multisine:3:0.1:5:-3:2.5");
  const auto x = sampled(t, 1.0 / 0.1);
  EXPECT_EQ(*std::min_element(x.begin(), x.end()), -3.0);
  EXPECT_EQ(*std::max_element(x.begin(), x.end()), 2.5);
  // Between the samples too (off the 1 ms grid), and over later periods.
  for (double s = 0.0; s < 40.0; s += 0.000373) {
    const double v = t.at(s);
    ASSERT_GE(v, -3.0) << s;
    ASSERT_LE(v, 2.5) << s;
  }
}

TEST(Trajectory, MultisineIsPeriodicAndReproducible) {
  const auto a = Trajectory::parse("multisine:7:0.2:4:-2:2");
  const auto b = Trajectory::parse("multisine:7:0.2:4:-2:2");
  const auto c = Trajectory::parse("multisine:8:0.2:4:-2:2");
  EXPECT_DOUBLE_EQ(a.duration, 5.0);
  double diff = 0.0;
  for (int i = 0; i < 5000; ++i) {
    const double s = i * 1e-3;
    ASSERT_EQ(a.at(s), b.at(s));
    EXPECT_NEAR(a.at(s), a.at(s + 5.0), 1e-9);
    diff = std::max(diff, std::fabs(a.at(s) - c.at(s)));
  }
  EXPECT_GT(diff, 0.5);  // another seed, other phases: another signal
}

TEST(Trajectory, MultisinePowerLiesInItsBand) {
  // Lines at 0.5, 1.0, ..., 8 Hz; one 2 s period at 1 kHz: DFT bin k is k * 0.5 Hz.
  const auto t = Trajectory::parse("multisine:11:0.5:8:-1:4");
  const auto p = power(sampled(t, 2.0));
  double in = 0.0, out = 0.0, lo = INFINITY, hi = 0.0;
  for (std::size_t k = 1; k < p.size(); ++k) {
    if (k <= 16) {
      in += p[k];
      lo = std::min(lo, p[k]);
      hi = std::max(hi, p[k]);
    } else {
      out += p[k];
    }
  }
  EXPECT_LT(out, 1e-6 * in);
  EXPECT_LT(hi / lo, 1.0 + 1e-6);  // equal amplitudes: every line carries the same power
}

TEST(Trajectory, MultisineRefusesWhatItCannotBe) {
  for (const char* spec : {"multisine:1:0:5:-3:3", "multisine:1:2:1:-3:3", "multisine:1:0.1:5:3:-3",
                           "multisine:1:0.1:500:-3:3", "multisine:1.5:0.1:5:-3:3", "multisine:1:0.1:5:-3"}) {
    try {
      Trajectory::parse(spec);
      ADD_FAILURE() << spec << " accepted";
    } catch (const std::invalid_argument& e) {
      EXPECT_NE(std::string(e.what()).find(std::string("'") + spec + "'"), std::string::npos) << e.what();
      EXPECT_EQ(std::string(e.what()).find('\n'), std::string::npos);
    }
  }
}

TEST(Trajectory, AprbsHoldsLevelsWithinBounds) {
  const auto t = Trajectory::parse("aprbs:5:0.2:1.5:-2.5:3");
  ASSERT_GE(t.knot_t.size(), 4u);
  double lo = INFINITY, hi = -INFINITY;
  for (std::size_t i = 0; i + 1 < t.knot_t.size(); i += 2) {
    EXPECT_EQ(t.knot_v[i], t.knot_v[i + 1]);  // a level held
    const double hold = t.knot_t[i + 1] - t.knot_t[i];
    EXPECT_GE(hold, 0.2 - 1e-12);
    EXPECT_LE(hold, 1.5 + 1e-12);
    if (i + 2 < t.knot_t.size()) {
      EXPECT_EQ(t.knot_t[i + 2], t.knot_t[i + 1]);  // the next level at once
    }
    lo = std::min(lo, t.knot_v[i]);
    hi = std::max(hi, t.knot_v[i]);
  }
  EXPECT_GE(lo, -2.5);
  EXPECT_LE(hi, 3.0);
  EXPECT_LT(lo, -2.0);  // uniform over the range: 1200 s of levels reach near both ends
  EXPECT_GT(hi, 2.5);
  // Evaluated: piecewise constant, each value one of the levels, within the range.
  const auto x = sampled(t, 60.0);
  int jumps = 0;
  for (std::size_t i = 1; i < x.size(); ++i) {
    ASSERT_GE(x[i], -2.5);
    ASSERT_LE(x[i], 3.0);
    jumps += x[i] != x[i - 1];
  }
  EXPECT_GE(jumps, 60 / 1.5 - 1);
  EXPECT_LE(jumps, 60 / 0.2 + 1);
}

TEST(Trajectory, AprbsIsReproducibleAndSeedsDiffer) {
  const auto a = Trajectory::parse("aprbs:1:0.05:0.5:-3:3");
  const auto b = Trajectory::parse("aprbs:1:0.05:0.5:-3:3");
  const auto c = Trajectory::parse("aprbs:2:0.05:0.5:-3:3");
  EXPECT_EQ(a.knot_t, b.knot_t);
  EXPECT_EQ(a.knot_v, b.knot_v);
  EXPECT_NE(a.knot_v, c.knot_v);
  EXPECT_THROW(Trajectory::parse("aprbs:1:0.001:0.5:-3:3"), std::invalid_argument);  // below the shortest hold
  EXPECT_THROW(Trajectory::parse("aprbs:1:0.5:0.2:-3:3"), std::invalid_argument);
  EXPECT_THROW(Trajectory::parse("aprbs:1:0.05:0.5:3:3"), std::invalid_argument);
}

TEST(Trajectory, EveryFormParsesAndDescribesItself) {
  // The forms of the table, one example each, with their describe() naming the shape.
  const std::vector<std::pair<std::string, std::string>> cases = {{"const:15", "constant"},
                                                                  {"sine:0.1:15:5", "sin"},
                                                                  {"triangle:0.05:0.2:30", "triangle"},
                                                                  {"square:0.1:10:25", "square"},
                                                                  {"sawtooth:0.1:10:25", "sawtooth"},
                                                                  {"sinedesc:0.1:15:14:2:60", "amplitude"},
                                                                  {"chirp:0.02:2:0.2:2.9:60", "chirp"},
                                                                  {"random:1:-3:3", "random"},
                                                                  {"multisine:1:0.05:5:-3:3", "multisine"},
                                                                  {"aprbs:1:0.1:2:-3:3", "APRBS"}};
  std::string forms = Trajectory::forms();
  for (const auto& [spec, word] : cases) {
    const auto t = Trajectory::parse(spec);
    EXPECT_NE(t.describe().find(word), std::string::npos) << spec << ": " << t.describe();
    const std::string name = spec.substr(0, spec.find(':'));
    EXPECT_NE(forms.find(name + ":"), std::string::npos) << name;
  }
  EXPECT_THROW(Trajectory::parse("triangle:0.05:0.2"), std::invalid_argument);
  EXPECT_THROW(Trajectory::parse("wobble:1"), std::invalid_argument);
}
