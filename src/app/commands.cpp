#include <cstdio>
#include <sstream>

#include "app/command.hpp"

namespace pamc::app {

std::vector<std::string> splitList(const std::string& s) {
  std::vector<std::string> out;
  std::stringstream ss(s);
  std::string p;
  while (std::getline(ss, p, ','))
    if (!p.empty()) out.push_back(p);
  return out;
}

void progressLine(const std::string& m) { std::fprintf(stderr, "%s\n", m.c_str()); }

void printWarnings(std::vector<std::string>& warnings) {
  for (const auto& w : warnings) std::fprintf(stderr, "warning: %s\n", w.c_str());
  warnings.clear();
}

}  // namespace pamc::app
