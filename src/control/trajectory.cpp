#include "control/trajectory.hpp"

#include <algorithm>
#include <cmath>
#include <random>
#include <cstdio>
#include <sstream>
#include <stdexcept>
#include <vector>

namespace pamc::control {

double Trajectory::at(double t) const noexcept {
  const double ph = freq_hz * t - std::floor(freq_hz * t);  // phase in [0,1)
  switch (shape) {
    case Shape::Constant: return offset;
    case Shape::Sine: return offset + amplitude * std::sin(2.0 * M_PI * freq_hz * t);
    case Shape::Triangle: return lo + (hi - lo) * (ph < 0.5 ? 2.0 * ph : 2.0 - 2.0 * ph);
    case Shape::Square: return ph < 0.5 ? hi : lo;
    case Shape::Sawtooth: return lo + (hi - lo) * ph;
    case Shape::SineDescending: {
      const double f = duration > 0 ? std::min(std::max(t / duration, 0.0), 1.0) : 0.0;
      const double a = amplitude + (amplitude_end - amplitude) * f;
      return offset - a * std::cos(2.0 * M_PI * freq_hz * t + phase);
    }
    case Shape::Chirp: {
      const double tt = duration > 0 ? std::min(std::max(t, 0.0), duration) : t;
      const double k = duration > 0 ? (freq_end_hz - freq_hz) / duration : 0.0;
      return offset + amplitude * std::sin(2.0 * M_PI * (freq_hz * tt + 0.5 * k * tt * tt));
    }
    case Shape::RandomRampHold: {
      if (knot_t.size() < 2) return lo;
      const double tt = std::fmod(std::max(t, 0.0), knot_t.back());
      const auto it = std::upper_bound(knot_t.begin(), knot_t.end(), tt);
      const size_t i = static_cast<size_t>(std::max<long>(1, it - knot_t.begin()));
      if (i >= knot_t.size()) return knot_v.back();
      const double f = (tt - knot_t[i - 1]) / (knot_t[i] - knot_t[i - 1]);
      return knot_v[i - 1] + f * (knot_v[i] - knot_v[i - 1]);
    }
  }
  return 0.0;
}

std::string Trajectory::describe() const {
  char b[160];
  switch (shape) {
    case Shape::Constant: std::snprintf(b, sizeof b, "constant %g", offset); break;
    case Shape::Sine: std::snprintf(b, sizeof b, "%g sin(2 pi %g t) + %g", amplitude, freq_hz, offset); break;
    case Shape::Triangle: std::snprintf(b, sizeof b, "%g Hz triangle %g-%g", freq_hz, lo, hi); break;
    case Shape::Square: std::snprintf(b, sizeof b, "%g Hz square %g-%g", freq_hz, lo, hi); break;
    case Shape::Sawtooth: std::snprintf(b, sizeof b, "%g Hz sawtooth %g-%g", freq_hz, lo, hi); break;
    case Shape::SineDescending:
      std::snprintf(b, sizeof b, "%g Hz sine about %g, amplitude %g -> %g over %g s%s", freq_hz, offset, amplitude,
                    amplitude_end, duration,
                    phase == 0.0 ? "" : std::fabs(phase - M_PI / 2) < 1e-12 ? ", from the centre" : ", phase shifted");
      break;
    case Shape::Chirp:
      std::snprintf(b, sizeof b, "chirp %g -> %g Hz over %g s, %g sin + %g", freq_hz, freq_end_hz, duration, amplitude, offset);
      break;
    case Shape::RandomRampHold: std::snprintf(b, sizeof b, "random ramps and holds in [%g, %g]", lo, hi); break;
  }
  return b;
}

Trajectory Trajectory::constant(double v) {
  Trajectory t;
  t.offset = t.lo = t.hi = v;
  return t;
}
Trajectory Trajectory::sine(double f, double a, double o) {
  Trajectory t;
  t.shape = Shape::Sine;
  t.freq_hz = f;
  t.amplitude = a;
  t.offset = o;
  t.lo = o - a;
  t.hi = o + a;
  return t;
}
Trajectory Trajectory::triangle(double f, double lo, double hi) {
  Trajectory t;
  t.shape = Shape::Triangle;
  t.freq_hz = f;
  t.lo = lo;
  t.hi = hi;
  return t;
}
Trajectory Trajectory::square(double f, double lo, double hi) {
  Trajectory t = triangle(f, lo, hi);
  t.shape = Shape::Square;
  return t;
}
Trajectory Trajectory::sawtooth(double f, double lo, double hi) {
  Trajectory t = triangle(f, lo, hi);
  t.shape = Shape::Sawtooth;
  return t;
}
Trajectory Trajectory::sineDescending(double f, double c, double a0, double a1, double d, double phase) {
  Trajectory t;
  t.shape = Shape::SineDescending;
  t.freq_hz = f;
  t.offset = c;
  t.amplitude = a0;
  t.amplitude_end = a1;
  t.duration = d;
  t.phase = phase;
  t.lo = c - a0;
  t.hi = c + a0;
  return t;
}

Trajectory Trajectory::chirp(double f0, double f1, double offset, double amplitude, double duration) {
  Trajectory t;
  t.shape = Shape::Chirp;
  t.freq_hz = f0;
  t.freq_end_hz = f1;
  t.offset = offset;
  t.amplitude = amplitude;
  t.duration = duration;
  t.lo = offset - amplitude;
  t.hi = offset + amplitude;
  return t;
}

Trajectory Trajectory::randomRampHold(std::uint64_t seed, double lo, double hi) {
  Trajectory t;
  t.shape = Shape::RandomRampHold;
  t.lo = lo;
  t.hi = hi;
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> U(0.0, 1.0);
  double now = 0.0, v = lo + (hi - lo) * U(rng);
  t.knot_t.push_back(now);
  t.knot_v.push_back(v);
  while (now < 1200.0) {
    // Ramp durations and holds spread log-uniformly so slow and fast both appear.
    const double ramp = 0.05 * std::pow(60.0, U(rng));
    const double hold = 0.1 * std::pow(30.0, U(rng));
    v = lo + (hi - lo) * U(rng);
    now += ramp;
    t.knot_t.push_back(now);
    t.knot_v.push_back(v);
    now += hold;
    t.knot_t.push_back(now);
    t.knot_v.push_back(v);
  }
  t.duration = now;
  return t;
}

Trajectory Trajectory::parse(const std::string& spec) {
  std::vector<std::string> parts;
  std::stringstream ss(spec);
  std::string p;
  while (std::getline(ss, p, ':')) parts.push_back(p);
  auto bad = [&](const std::string& why) {
    throw std::invalid_argument("trajectory '" + spec + "': " + why +
                                " (forms: const:Y, sine:F:CENTRE:AMP, triangle:F:LO:HI, square:F:LO:HI, "
                                "sawtooth:F:LO:HI, sinedesc:F:CENTRE:A0:A1:DURATION[:PHASE_DEG], chirp:F0:F1:OFFSET:AMP:DURATION, random:SEED:LO:HI)");
  };
  if (parts.empty()) bad("empty");
  std::vector<double> v;
  for (size_t i = 1; i < parts.size(); ++i) {
    char* end = nullptr;
    const double d = std::strtod(parts[i].c_str(), &end);
    if (parts[i].empty() || *end != '\0' || !std::isfinite(d)) bad("'" + parts[i] + "' is not a number");
    v.push_back(d);
  }
  const std::string& k = parts[0];
  auto need = [&](size_t n) {
    if (v.size() != n) bad("expected " + std::to_string(n) + " numbers after '" + k + "'");
  };
  if (k == "const") { need(1); return constant(v[0]); }
  if (k == "sine") { need(3); return sine(v[0], v[2], v[1]); }
  if (k == "triangle") { need(3); return triangle(v[0], v[1], v[2]); }
  if (k == "square") { need(3); return square(v[0], v[1], v[2]); }
  if (k == "sawtooth") { need(3); return sawtooth(v[0], v[1], v[2]); }
  if (k == "sinedesc") {
    if (v.size() != 6) need(5);
    return sineDescending(v[0], v[1], v[2], v[3], v[4], v.size() == 6 ? v[5] * M_PI / 180.0 : 0.0);
  }
  if (k == "chirp") { need(5); return chirp(v[0], v[1], v[2], v[3], v[4]); }
  if (k == "random") {
    need(3);
    if (v[0] < 0 || v[0] != std::floor(v[0])) bad("the seed must be a non-negative integer");
    return randomRampHold(static_cast<std::uint64_t>(v[0]), v[1], v[2]);
  }
  bad("unknown shape '" + k + "'");
  return {};
}

}  // namespace pamc::control
