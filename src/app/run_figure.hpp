// A run of the rig as a picture: `pamc rig run --figure FILE.png` draws each joint's angle against its
// trajectory, each channel's position against its setpoint and its command, from the CSV written next
// to it (FILE.csv: t, then per channel yd<c>, y<c>, u<c>, per joint angle_d<j>, angle<j>).
#pragma once

#include <string>
#include <vector>

#include "nodes/cycle_stats.hpp"
#include "nodes/rig_file.hpp"

namespace pamc::app {

// The angle of a joint's flexor position y [mm]: (y - rest) / lever [deg].
double jointAngleDeg(const nodes::RigJoint& j, double y_flexor_mm);

// Writes png and its CSV; a missing gnuplot is a warning (the CSV stays). Throws std::runtime_error when
// the CSV cannot be written.
void writeRunFigure(const std::string& png, const std::vector<nodes::CycleRecord>& recs, std::size_t channels,
                    const std::vector<nodes::RigJoint>& joints);

}  // namespace pamc::app
