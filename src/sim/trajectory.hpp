// Reference signals of the paper's experiments: desired positions for closed-loop runs
// and open-loop excitation voltages for identification.
#pragma once

#include <string>

namespace pamc::sim {

struct Trajectory {
  enum class Shape { Constant, Sine, Triangle, Square, Sawtooth, SineDescending };
  Shape shape = Shape::Constant;
  double freq_hz = 0.1;
  double lo = 0.0;   // lowest value (Triangle, Square, Sawtooth); centre - amplitude otherwise
  double hi = 0.0;   // highest value
  double offset = 0.0, amplitude = 0.0;   // Sine: offset + amplitude sin(2 pi f t)
  double amplitude_end = 0.0;             // SineDescending: amplitude at t = duration
  double duration = 0.0;                  // SineDescending

  double at(double t) const noexcept;
  std::string describe() const;

  static Trajectory constant(double v);
  static Trajectory sine(double freq, double amplitude, double offset);
  static Trajectory triangle(double freq, double lo, double hi);
  static Trajectory square(double freq, double lo, double hi);
  static Trajectory sawtooth(double freq, double lo, double hi);
  // centre - A(t) cos(2 pi f t): starts at the bottom; A falls linearly from a0 to a1 over `duration`.
  static Trajectory sineDescending(double freq, double centre, double a0, double a1, double duration);
  // Parses "triangle:0.05:0.2:30", "sine:0.05:15:14.9" (freq:centre:amplitude), "sinedesc:0.05:15.1:14.9:2:60",
  // "square:0.1:10:25", "sawtooth:0.1:10:25", "const:15". Throws std::invalid_argument.
  static Trajectory parse(const std::string& spec);
};

}  // namespace pamc::sim
