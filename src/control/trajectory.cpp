#include "control/trajectory.hpp"

#include <algorithm>
#include <cmath>
#include <random>
#include <cstdio>
#include <sstream>
#include <stdexcept>
#include <vector>

#include "io/text.hpp"

namespace pamc::control {
namespace {

// Lines of a multisine: the multiples of f0 up to f1 (a hair of tolerance so that f1 = k f0 is one).
std::size_t multisineLines(double f0, double f1) {
  return f0 > 0.0 ? static_cast<std::size_t>(std::floor(f1 / f0 * (1.0 + 1e-12))) : 0;
}

}  // namespace

Trajectory Trajectory::mapped(double scale, double offset) const {
  Trajectory m = *this;
  m.map_offset = offset + scale * map_offset;
  m.map_scale = scale * map_scale;
  return m;
}

double Trajectory::shapeAt(double t) const noexcept {
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
    case Shape::Multisine: return uniformTable(t);
    case Shape::RandomRampHold:
    case Shape::Aprbs: {
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

// Multisine: samples at an even step over one period, linear between them (the last joins the first).
double Trajectory::uniformTable(double t) const noexcept {
  const std::size_t n = knot_v.size();
  if (n == 0 || !(duration > 0.0)) return lo;
  double x = std::fmod(std::max(t, 0.0), duration) / duration * static_cast<double>(n);
  // On a sample (a cycle of the loop that the table's step divides) to within rounding: that sample.
  if (const double r = std::round(x); std::fabs(x - r) < 1e-6) x = r < static_cast<double>(n) ? r : 0.0;
  const std::size_t i = std::min(static_cast<std::size_t>(x), n - 1);
  const double f = x - static_cast<double>(i);
  const double v = knot_v[i] + f * (knot_v[(i + 1) % n] - knot_v[i]);
  return std::clamp(v, lo, hi);  // a rounding of the interpolation never leaves [lo, hi]
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
                    phase == 0.0                          ? ""
                    : std::fabs(phase - M_PI / 2) < 1e-12 ? ", from the centre"
                                                          : ", phase shifted");
      break;
    case Shape::Chirp:
      std::snprintf(b, sizeof b, "chirp %g -> %g Hz over %g s, %g sin + %g", freq_hz, freq_end_hz, duration, amplitude,
                    offset);
      break;
    case Shape::RandomRampHold: std::snprintf(b, sizeof b, "random ramps and holds in [%g, %g]", lo, hi); break;
    case Shape::Multisine:
      std::snprintf(b, sizeof b, "multisine %g-%g Hz (%zu lines, period %g s, seed %llu) in [%g, %g]", freq_hz,
                    freq_end_hz, multisineLines(freq_hz, freq_end_hz), duration, static_cast<unsigned long long>(seed),
                    lo, hi);
      break;
    case Shape::Aprbs:
      std::snprintf(b, sizeof b, "APRBS in [%g, %g], holds %g-%g s (seed %llu)", lo, hi, hold_min, hold_max,
                    static_cast<unsigned long long>(seed));
      break;
  }
  if (map_scale == 1.0 && map_offset == 0.0) return b;
  char m[64];
  std::snprintf(m, sizeof m, ", mapped to %g + %g x", map_offset, map_scale);
  return std::string(b) + m;
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
  t.seed = seed;
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

namespace {

// One period of sum_k sin(2 pi k i / n + phase_k), k = 1..lines, from tables of sin and cos over the
// period (k i taken modulo n: exact periodicity, no phase drift).
std::vector<double> multisineSamples(const std::vector<double>& phases, std::size_t n) {
  std::vector<double> s(n), c(n), x(n, 0.0);
  for (std::size_t j = 0; j < n; ++j) {
    const double a = 2.0 * M_PI * static_cast<double>(j) / static_cast<double>(n);
    s[j] = std::sin(a);
    c[j] = std::cos(a);
  }
  for (std::size_t k = 1; k <= phases.size(); ++k) {
    const double cp = std::cos(phases[k - 1]), sp = std::sin(phases[k - 1]);
    std::size_t j = 0;  // k i mod n
    for (std::size_t i = 0; i < n; ++i, j = (j + k) % n) x[i] += s[j] * cp + c[j] * sp;
  }
  return x;
}

// Affine map of x onto [lo, hi]: its minimum exactly lo, its maximum exactly hi.
void scaleOnto(std::vector<double>& x, double lo, double hi) {
  const auto [mn_it, mx_it] = std::minmax_element(x.begin(), x.end());
  const double mn = *mn_it, mx = *mx_it;
  const std::size_t i_mn = static_cast<std::size_t>(mn_it - x.begin()),
                    i_mx = static_cast<std::size_t>(mx_it - x.begin());
  for (double& v : x) v = std::clamp(lo + (hi - lo) * (v - mn) / (mx - mn), lo, hi);
  x[i_mn] = lo;
  x[i_mx] = hi;
}

}  // namespace

Trajectory Trajectory::multisine(std::uint64_t seed, double f0, double f1, double lo, double hi) {
  auto bad = [](const std::string& why) { throw std::invalid_argument(why); };
  if (!(f0 > 0.0 && f0 <= f1)) bad("the band needs 0 < F0 <= F1");
  if (f1 > kMultisineMaxHz) bad("F1 must be at most " + io::fmt("%g", kMultisineMaxHz) + " Hz");
  if (!(lo < hi)) bad("LO must be below HI");
  const double period = 1.0 / f0;
  if (period > kMaxTablePeriod_s)
    bad("F0 must be at least 1/" + io::fmt("%g", kMaxTablePeriod_s) + " Hz (a period of at most " +
        io::fmt("%g", kMaxTablePeriod_s) + " s)");
  const std::size_t lines = multisineLines(f0, f1);
  const auto n = static_cast<std::size_t>(std::ceil(period / kMultisineStep_s - 1e-9));
  // The tables cost lines x samples: keep the build well under a second.
  if (static_cast<double>(lines) * static_cast<double>(n) > 2e8)
    bad(std::to_string(lines) + " lines over a " + std::to_string(n) +
        "-sample period is too many: raise F0 or lower F1");
  Trajectory t;
  t.shape = Shape::Multisine;
  t.seed = seed;
  t.freq_hz = f0;
  t.freq_end_hz = f1;
  t.lo = lo;
  t.hi = hi;
  t.duration = period;
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> phase(0.0, 2.0 * M_PI);
  std::vector<double> phases(lines);
  for (double& p : phases) p = phase(rng);
  t.knot_v = multisineSamples(phases, n);
  scaleOnto(t.knot_v, lo, hi);
  return t;
}

Trajectory Trajectory::aprbs(std::uint64_t seed, double hold_min, double hold_max, double lo, double hi) {
  if (!(hold_min >= kAprbsMinHold_s && hold_min <= hold_max) || !std::isfinite(hold_max))
    throw std::invalid_argument("the holds need " + io::fmt("%g", kAprbsMinHold_s) + " s <= HOLD_MIN <= HOLD_MAX");
  if (!(lo < hi)) throw std::invalid_argument("LO must be below HI");
  Trajectory t;
  t.shape = Shape::Aprbs;
  t.seed = seed;
  t.hold_min = hold_min;
  t.hold_max = hold_max;
  t.lo = lo;
  t.hi = hi;
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> level(lo, hi), hold(hold_min, hold_max);
  double now = 0.0;
  while (now < kMaxTablePeriod_s) {
    // A level and its hold: two knots at one value (the jump to the next level is the next knot).
    const double v = level(rng);
    t.knot_t.push_back(now);
    t.knot_v.push_back(v);
    now += hold_min == hold_max ? hold_min : hold(rng);
    t.knot_t.push_back(now);
    t.knot_v.push_back(v);
  }
  t.duration = now;
  return t;
}

namespace {

using Numbers = std::vector<double>;

std::uint64_t seedOf(double v) {
  if (v < 0 || v != std::floor(v) || v > 9.0e15) throw std::invalid_argument("the seed must be a non-negative integer");
  return static_cast<std::uint64_t>(v);
}

// The forms parse() takes, one row each: its name, its numbers, how many (a second count: optional
// numbers allowed), and how the numbers make it.
struct Form {
  const char* name;
  const char* numbers;
  std::size_t count, count_max;
  Trajectory (*make)(const Numbers&);
};

constexpr Form kForms[] = {
    {"const", "Y", 1, 1, [](const Numbers& v) { return Trajectory::constant(v[0]); }},
    {"sine", "F:CENTRE:AMP", 3, 3, [](const Numbers& v) { return Trajectory::sine(v[0], v[2], v[1]); }},
    {"triangle", "F:LO:HI", 3, 3, [](const Numbers& v) { return Trajectory::triangle(v[0], v[1], v[2]); }},
    {"square", "F:LO:HI", 3, 3, [](const Numbers& v) { return Trajectory::square(v[0], v[1], v[2]); }},
    {"sawtooth", "F:LO:HI", 3, 3, [](const Numbers& v) { return Trajectory::sawtooth(v[0], v[1], v[2]); }},
    {"sinedesc", "F:CENTRE:A0:A1:DURATION[:PHASE_DEG]", 5, 6,
     [](const Numbers& v) {
       return Trajectory::sineDescending(v[0], v[1], v[2], v[3], v[4], v.size() == 6 ? v[5] * M_PI / 180.0 : 0.0);
     }},
    {"chirp", "F0:F1:OFFSET:AMP:DURATION", 5, 5,
     [](const Numbers& v) { return Trajectory::chirp(v[0], v[1], v[2], v[3], v[4]); }},
    {"random", "SEED:LO:HI", 3, 3,
     [](const Numbers& v) { return Trajectory::randomRampHold(seedOf(v[0]), v[1], v[2]); }},
    {"multisine", "SEED:F0:F1:LO:HI", 5, 5,
     [](const Numbers& v) { return Trajectory::multisine(seedOf(v[0]), v[1], v[2], v[3], v[4]); }},
    {"aprbs", "SEED:HOLD_MIN:HOLD_MAX:LO:HI", 5, 5,
     [](const Numbers& v) { return Trajectory::aprbs(seedOf(v[0]), v[1], v[2], v[3], v[4]); }},
};

std::vector<std::string> splitSpec(const std::string& spec) {
  std::vector<std::string> parts;
  std::stringstream ss(spec);
  std::string p;
  while (std::getline(ss, p, ':')) parts.push_back(p);
  return parts;
}

// The numbers after the name; throws with the one that is not a number.
Numbers specNumbers(const std::vector<std::string>& parts) {
  Numbers v;
  for (std::size_t i = 1; i < parts.size(); ++i) {
    char* end = nullptr;
    const double d = std::strtod(parts[i].c_str(), &end);
    if (parts[i].empty() || *end != '\0' || !std::isfinite(d))
      throw std::invalid_argument("'" + parts[i] + "' is not a number");
    v.push_back(d);
  }
  return v;
}

const Form& formNamed(const std::string& name, std::size_t numbers) {
  for (const Form& f : kForms) {
    if (name != f.name) continue;
    if (numbers < f.count || numbers > f.count_max)
      throw std::invalid_argument("expected " + std::to_string(f.count) + " numbers after '" + name + "' (" + f.name +
                                  ":" + f.numbers + ")");
    return f;
  }
  throw std::invalid_argument("unknown shape '" + name + "'");
}

}  // namespace

std::string Trajectory::forms() {
  std::string s;
  for (const Form& f : kForms) s += std::string(s.empty() ? "" : ", ") + f.name + ":" + f.numbers;
  return s;
}

Trajectory Trajectory::parse(const std::string& spec) {
  try {
    const auto parts = splitSpec(spec);
    if (parts.empty()) throw std::invalid_argument("empty");
    const Numbers v = specNumbers(parts);
    return formNamed(parts[0], v.size()).make(v);
  } catch (const std::invalid_argument& e) {
    throw std::invalid_argument("trajectory '" + spec + "': " + e.what() + " (forms: " + forms() + ")");
  }
}

}  // namespace pamc::control
