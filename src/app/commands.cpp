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

CLI::Option* addOutputFormOption(CLI::App* cmd, std::string& form) {
  return cmd
      ->add_option("--output-form", form,
                   "aligned: y_k from the hysteresis state after u_k's increment (the continuous model's timing); "
                   "printed: eq. (6) as printed, y_k from h before it, one sample behind (docs/MODEL.md)")
      ->capture_default_str()
      ->check(CLI::IsMember({"aligned", "printed"}));
}

model::OutputForm outputFormOf(const std::string& form) {
  model::OutputForm f = model::OutputForm::Aligned;
  model::parseOutputForm(form, f);
  return f;
}

}  // namespace pamc::app
