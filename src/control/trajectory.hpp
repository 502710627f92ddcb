// Reference signals of the paper's experiments: desired positions for closed-loop runs
// and open-loop excitation voltages for identification.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

namespace pamc::control {

struct Trajectory {
  enum class Shape { Constant, Sine, Triangle, Square, Sawtooth, SineDescending, Chirp, RandomRampHold };
  Shape shape = Shape::Constant;
  double freq_hz = 0.1;
  double lo = 0.0;   // lowest value (Triangle, Square, Sawtooth); centre - amplitude otherwise
  double hi = 0.0;   // highest value
  double offset = 0.0, amplitude = 0.0;   // Sine: offset + amplitude sin(2 pi f t)
  double amplitude_end = 0.0;             // SineDescending: amplitude at t = duration
  double duration = 0.0;                  // SineDescending, Chirp: length; RandomRampHold: period of the table
  // SineDescending: phase added to 2 pi f t [rad]; 0 starts at the trough, pi/2 at the centre, rising.
  double phase = 0.0;
  double freq_end_hz = 0.0;               // Chirp: frequency at t = duration
  // RandomRampHold: ramps to random levels in [lo, hi] at random rates, then holds (t, value knots).
  std::vector<double> knot_t, knot_v;

  double at(double t) const noexcept;
  std::string describe() const;

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
  // Parses "triangle:0.05:0.2:30", "sine:0.05:15:14.9" (freq:centre:amplitude), "sinedesc:0.05:15.1:14.9:2:60"
  // (a sixth number: the phase in degrees),
  // "square:0.1:10:25", "sawtooth:0.1:10:25", "const:15", "chirp:0.02:2:0.2:2.9:60" (f0:f1:offset:amp:duration),
  // "random:SEED:LO:HI". Throws std::invalid_argument.
  static Trajectory parse(const std::string& spec);
};

}  // namespace pamc::control
