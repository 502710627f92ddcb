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

namespace {
int g_old_spelling_notices = 0;
}  // namespace

int oldSpellingNotices() { return g_old_spelling_notices; }

std::string commandPath(const CLI::App* cmd) {
  std::string path;
  for (const CLI::App* a = cmd; a != nullptr && a->get_parent() != nullptr; a = a->get_parent())
    path = a->get_name() + (path.empty() ? "" : " ") + path;
  return path;
}

void oldSpellingNotice(const std::string& old_usage, const std::string& new_usage) {
  ++g_old_spelling_notices;
  std::fprintf(stderr, "pamc: note: '%s' is now '%s' (the old spelling works until pamc %s)\n", old_usage.c_str(),
               new_usage.c_str(), kOldSpellingsUntil);
}

CLI::Option* addOldFlag(CLI::App* cmd, const std::string& old_name, const std::string& new_usage, bool& var) {
  const std::string old_usage = commandPath(cmd) + " " + old_name;
  return cmd
      ->add_flag_callback(old_name,
                          [&var, old_usage, new_usage] {
                            var = true;
                            oldSpellingNotice(old_usage, new_usage);
                          })
      ->group("");
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
