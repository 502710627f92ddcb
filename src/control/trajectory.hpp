// Reference signals of the paper's experiments: desired positions for closed-loop runs
// and open-loop excitation voltages for identification.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

namespace pamc::control {

struct Trajectory {
  enum class Shape {
    Constant,
    Sine,
    Triangle,
    Square,
    Sawtooth,
    SineDescending,
    Chirp,
    RandomRampHold,
    Multisine,
    Aprbs
  };
  Shape shape = Shape::Constant;
  double freq_hz = 0.1;
  double lo = 0.0;                       // lowest value (Triangle, Square, Sawtooth); centre - amplitude otherwise
  double hi = 0.0;                       // highest value
  double offset = 0.0, amplitude = 0.0;  // Sine: offset + amplitude sin(2 pi f t)
  double amplitude_end = 0.0;            // SineDescending: amplitude at t = duration
  double duration = 0.0;  // SineDescending, Chirp: length; RandomRampHold, Multisine, Aprbs: period of the table
  // SineDescending: phase added to 2 pi f t [rad]; 0 starts at the trough, pi/2 at the centre, rising.
  double phase = 0.0;
  double freq_end_hz = 0.0;               // Chirp: frequency at t = duration
  double hold_min = 0.0, hold_max = 0.0;  // Aprbs: each level held for a time in [hold_min, hold_max] s
  std::uint64_t seed = 0;                 // RandomRampHold, Multisine, Aprbs
  // The shapes made of a table, read as a periodic piecewise-linear curve through (t, value) knots
  // (knot_t increasing, from 0 to the period): RandomRampHold's ramps and holds, Multisine's samples,
  // Aprbs's levels (a jump is two knots at one time). Built at construction; at() only reads them.
  std::vector<double> knot_t, knot_v;
  // The shape seen through a linear map, value = map_offset + map_scale * shape (mapped()): a joint's
  // angle in degrees as one muscle's contraction in mm.
  double map_scale = 1.0, map_offset = 0.0;

  double at(double t) const noexcept { return map_offset + map_scale * shapeAt(t); }
  double shapeAt(double t) const noexcept;  // before the map
  Trajectory mapped(double scale, double offset) const;
  std::string describe() const;
  double uniformTable(double t) const noexcept;  // Multisine: knot_v at an even step over `duration`

  static Trajectory constant(double v);
  static Trajectory sine(double freq, double amplitude, double offset);
  static Trajectory triangle(double freq, double lo, double hi);
  static Trajectory square(double freq, double lo, double hi);
  static Trajectory sawtooth(double freq, double lo, double hi);
  // centre - A(t) cos(2 pi f t + phase): with phase 0 it starts at the bottom, with pi/2 at the centre
  // rising; A falls linearly from a0 to a1 over `duration`.
  static Trajectory sineDescending(double freq, double centre, double a0, double a1, double duration,
                                   double phase = 0.0);
  // offset + amplitude sin(phase), frequency sweeping linearly from f0 to f1 over `duration`.
  static Trajectory chirp(double f0, double f1, double offset, double amplitude, double duration);
  // Random ramps and holds over [lo, hi] (ramps 0.05-3 s, holds 0.1-3 s), reproducible from `seed`;
  // excites rates, levels, reversals and holds alike - the input for finding missing effects.
  static Trajectory randomRampHold(std::uint64_t seed, double lo, double hi);
  // Random-phase multisine: equal-amplitude lines at every multiple of f0 from f0 to f1 (so the period is
  // 1/f0), phases uniform from `seed`, sampled every kMultisineStep_s (or finer, so that the period is a
  // whole number of samples) and scaled so that the samples' minimum is exactly lo and their maximum
  // exactly hi; between samples linear (never outside [lo, hi]). Throws std::invalid_argument when
  // 0 < f0 <= f1 <= kMultisineMaxHz or lo < hi does not hold, or the period exceeds kMaxTablePeriod_s.
  static Trajectory multisine(std::uint64_t seed, double f0, double f1, double lo, double hi);
  // Amplitude-modulated pseudo-random binary sequence: levels uniform in [lo, hi], each held for a time
  // uniform in [hold_min, hold_max] s, reproducible from `seed`; the table covers kMaxTablePeriod_s and
  // then repeats. Throws std::invalid_argument unless kAprbsMinHold_s <= hold_min <= hold_max and lo < hi.
  static Trajectory aprbs(std::uint64_t seed, double hold_min, double hold_max, double lo, double hi);
  static constexpr double kMultisineStep_s = 1e-3;     // the cycle period: a 1 kHz loop reads the samples
  static constexpr double kMultisineMaxHz = 50.0;      // at least 20 samples per period of the highest line
  static constexpr double kAprbsMinHold_s = 0.01;      // 10 cycles at 1 kHz; bounds the table (120 000 levels)
  static constexpr double kMaxTablePeriod_s = 1200.0;  // the tables' length: a record longer than this repeats

  // Parses "triangle:0.05:0.2:30", "sine:0.05:15:14.9" (freq:centre:amplitude), "sinedesc:0.05:15.1:14.9:2:60"
  // (a sixth number: the phase in degrees),
  // "square:0.1:10:25", "sawtooth:0.1:10:25", "const:15", "chirp:0.02:2:0.2:2.9:60" (f0:f1:offset:amp:duration),
  // "random:SEED:LO:HI", "multisine:SEED:F0:F1:LO:HI", "aprbs:SEED:HOLD_MIN:HOLD_MAX:LO:HI" (forms()).
  // Throws std::invalid_argument naming the spec and the problem.
  static Trajectory parse(const std::string& spec);
  // The forms parse() takes, "const:Y, sine:F:CENTRE:AMP, ..." (for help texts and errors).
  static std::string forms();
};

}  // namespace pamc::control
