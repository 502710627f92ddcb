#include "app/completion.hpp"

#include <sstream>
#include <vector>

namespace pamc::app {
namespace {

// One command of the tree: its path of subcommand words (" rig run"), what follows it.
struct CommandWords {
  std::string path;
  std::vector<std::string> subcommands, options, value_options;
  std::vector<std::pair<std::string, std::string>> choices;  // option, its allowed values
};

bool hidden(const CLI::Option* o) { return o->get_group().empty(); }

// "TEXT:{a,b}=a" -> "a b"; empty when the option has no fixed set of values.
std::string choicesOf(const CLI::Option* o) {
  const std::string t = o->get_type_name();
  const auto open = t.find('{'), close = t.find('}');
  if (open == std::string::npos || close == std::string::npos || close < open) return "";
  std::string c = t.substr(open + 1, close - open - 1);
  for (auto& ch : c)
    if (ch == ',') ch = ' ';
  return c;
}

void collect(const CLI::App& app, const std::string& path, std::vector<CommandWords>& out) {
  CommandWords w;
  w.path = path;
  for (const CLI::App* s : app.get_subcommands([](const CLI::App*) { return true; })) {
    w.subcommands.push_back(s->get_name());
    collect(*s, path + " " + s->get_name(), out);
  }
  for (const CLI::Option* o : app.get_options()) {
    if (hidden(o) || o->get_lnames().empty()) continue;
    const std::string name = "--" + o->get_lnames().front();
    w.options.push_back(name);
    if (o->get_expected_max() == 0) continue;  // a flag
    w.value_options.push_back(name);
    if (auto c = choicesOf(o); !c.empty()) w.choices.emplace_back(name, c);
  }
  out.insert(out.begin(), w);
}

std::string joined(const std::vector<std::string>& v) {
  std::string s;
  for (const auto& x : v) s += (s.empty() ? "" : " ") + x;
  return s;
}

void writeCase(std::ostringstream& s, const CommandWords& w) {
  s << "    \"" << w.path << "\")\n";
  s << "      subs=\"" << joined(w.subcommands) << "\"; opts=\"" << joined(w.options) << "\"\n";
  s << "      valued=\" " << joined(w.value_options) << " \"\n";
  s << "      case \"$prev\" in\n";
  for (const auto& [opt, values] : w.choices) s << "        " << opt << ") choices=\"" << values << "\";;\n";
  s << "      esac;;\n";
}

}  // namespace

std::string bashCompletion(const CLI::App& app) {
  std::vector<CommandWords> tree;
  collect(app, "", tree);
  std::ostringstream s;
  s << "# bash completion for pamc: generated from its option tables by `pamc --bash-completion`.\n"
       "_pamc() {\n"
       "  local cur=${COMP_WORDS[COMP_CWORD]} prev=${COMP_WORDS[COMP_CWORD-1]}\n"
       "  local path=\"\" i w subs opts valued choices=\"\"\n"
       "  # The subcommand words before the cursor (an option's value is skipped with it).\n"
       "  for ((i = 1; i < COMP_CWORD; i++)); do\n"
       "    w=${COMP_WORDS[i]}\n"
       "    case \"$path $w\" in\n";
  for (const auto& w : tree)
    if (!w.path.empty()) s << "      \"" << w.path << "\") path=\"" << w.path << "\";;\n";
  s << "    esac\n"
       "  done\n"
       "  case \"$path\" in\n";
  for (const auto& w : tree) writeCase(s, w);
  s << "  esac\n"
       "  if [[ -n $choices ]]; then COMPREPLY=($(compgen -W \"$choices\" -- \"$cur\")); return; fi\n"
       "  if [[ $valued == *\" $prev \"* ]]; then COMPREPLY=($(compgen -f -- \"$cur\")); return; fi\n"
       "  if [[ $cur == -* ]]; then COMPREPLY=($(compgen -W \"$opts\" -- \"$cur\")); return; fi\n"
       "  if [[ -n $subs ]]; then COMPREPLY=($(compgen -W \"$subs\" -- \"$cur\")); return; fi\n"
       "  COMPREPLY=($(compgen -f -- \"$cur\"))\n"
       "}\n"
       "complete -o filenames -F _pamc pamc\n";
  return s.str();
}

}  // namespace pamc::app
