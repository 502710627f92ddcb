// Number formatting for reports (not for the 1 kHz path).
#pragma once

#include <cstdio>
#include <string>

namespace pamc::io {

// printf-style formatting of one number.
inline std::string fmt(const char* format, double v) {
  char b[64];
  std::snprintf(b, sizeof b, format, v);
  return b;
}

}  // namespace pamc::io
