#include "canopen/ini.hpp"

#include <ini.h>

#include <algorithm>
#include <cctype>
#include <cerrno>
#include <cmath>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <sstream>

namespace pamc::canopen {

namespace {

std::string lower(std::string s) {
  std::transform(s.begin(), s.end(), s.begin(), [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
  return s;
}

bool sameName(const std::string& a, const std::string& b) { return lower(a) == lower(b); }

struct State {
  IniFile* file;
  std::vector<std::string> lines;
  std::size_t next = 0;
  int lineno = 0;
  int err_line = 0;
  std::string err;
  // Values too long for inih's line buffer (a DOMAIN's hex bytes): inih gets a stand-in, onKey the value.
  std::vector<std::pair<int, std::string>> long_values;
  void fail(int line, std::string problem) {
    if (err_line != 0) return;  // the first problem in file order
    err_line = line;
    err = std::move(problem);
  }
};

constexpr const char* kLongValue = "\x01long value\x01";

// A "key = value" line beyond inih's buffer keeps its key; the value (trimmed, without an inline
// "; comment", as inih would leave it) waits in the state for onKey.
void shortenValue(State& st, std::string& line, std::size_t max_len) {
  const auto eq = line.find('=');
  const auto first = line.find_first_not_of(" \t");
  if (eq == std::string::npos || first == std::string::npos || line[first] == '[' || line[first] == ';' ||
      eq + 1 + std::strlen(kLongValue) > max_len) {
    st.fail(st.lineno, "line longer than " + std::to_string(max_len) + " characters");
    line.resize(max_len);
    return;
  }
  std::string value = line.substr(eq + 1);
  for (std::size_t c = value.find(';'); c != std::string::npos; c = value.find(';', c + 1))
    if (c > 0 && std::isspace(static_cast<unsigned char>(value[c - 1]))) {
      value.resize(c);
      break;
    }
  value.erase(0, value.find_first_not_of(" \t"));
  value.erase(value.find_last_not_of(" \t") + 1);
  st.long_values.emplace_back(st.lineno, std::move(value));
  line = line.substr(0, eq + 1) + kLongValue;
}

// fgets-style reader for ini_parse_stream: counting lines here gives every key its line.
char* readLine(char* str, int num, void* stream) {
  auto* st = static_cast<State*>(stream);
  if (st->next >= st->lines.size()) return nullptr;
  std::string line = st->lines[st->next++];
  st->lineno = static_cast<int>(st->next);
  if (st->lineno == 1 && line.compare(0, 3, "\xEF\xBB\xBF") == 0) line.erase(0, 3);
  if (!line.empty() && line.back() == '\r') line.pop_back();
  const std::size_t max_len = static_cast<std::size_t>(num) - 3;  // inih needs room for "\r\n\0"
  if (line.size() > max_len) shortenValue(*st, line, max_len);
  // Sections are opened here, at their header, so that an empty or repeated one is seen too.
  const auto p = line.find_first_not_of(" \t");
  if (p != std::string::npos && line[p] == '[') {
    const auto close = line.find(']', p);
    if (close != std::string::npos) {
      std::string name = line.substr(p + 1, close - p - 1);
      name.erase(0, name.find_first_not_of(" \t"));
      name.erase(name.find_last_not_of(" \t") + 1);
      for (const auto& s : st->file->sections)
        if (sameName(s.name, name))
          st->fail(st->lineno, "duplicate section [" + name + "] (first at line " + std::to_string(s.line) + ")");
      st->file->sections.push_back(IniSection{name, st->lineno, {}});
    }
  }
  std::memcpy(str, line.data(), line.size());
  str[line.size()] = '\n';
  str[line.size() + 1] = '\0';
  return str;
}

int onKey(void* user, const char* section, const char* name, const char* value) {
  auto* st = static_cast<State*>(user);
  auto& secs = st->file->sections;
  if (section[0] == '\0') {
    st->fail(st->lineno, std::string("key '") + name + "' outside of any section");
    return 0;
  }
  if (secs.empty() || !sameName(secs.back().name, section)) {
    st->fail(st->lineno, std::string("key '") + name + "' outside of section [" + section + "]");
    return 0;
  }
  IniSection& s = secs.back();
  if (s.find(name) != nullptr) {
    st->fail(st->lineno, std::string("duplicate key '") + name + "' in [" + section + "] (first at line " +
                             std::to_string(s.find(name)->line) + ")");
    return 0;
  }
  std::string v = value;
  if (v == kLongValue && !st->long_values.empty() && st->long_values.back().first == st->lineno)
    v = st->long_values.back().second;
  s.keys.push_back(IniKey{name, std::move(v), st->lineno});
  return 1;
}

}  // namespace

IniError::IniError(const std::string& file, int line, const std::string& problem)
    : std::runtime_error(file + (line > 0 ? ":" + std::to_string(line) : std::string()) + ": " + problem),
      file_(file),
      line_(line),
      problem_(problem) {}

const IniKey* IniSection::find(const std::string& key) const {
  for (const auto& k : keys)
    if (sameName(k.name, key)) return &k;
  return nullptr;
}

const IniSection* IniFile::find(const std::string& section) const {
  for (const auto& s : sections)
    if (sameName(s.name, section)) return &s;
  return nullptr;
}

IniFile parseIni(const std::string& text, const std::string& path) {
  IniFile f;
  f.path = path;
  State st;
  st.file = &f;
  std::istringstream in(text);
  for (std::string l; std::getline(in, l);) st.lines.push_back(l);
  const int rc = ini_parse_stream(readLine, &st, onKey, &st);
  // The first problem in file order: inih reports the first line it cannot parse, the hooks theirs.
  if (rc > 0 && (st.err_line == 0 || rc < st.err_line))
    throw IniError(path, rc, "syntax error: expected [section], key = value or a ; comment");
  if (st.err_line != 0) throw IniError(path, st.err_line, st.err);
  if (rc < 0) throw IniError(path, 0, "cannot be parsed");
  return f;
}

IniFile readIni(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw IniError(path, 0, "cannot open file");
  std::ostringstream ss;
  ss << in.rdbuf();
  return parseIni(ss.str(), path);
}

bool parseIniUnsigned(const std::string& text, std::uint64_t& out) {
  if (text.empty() || text[0] == '-' || text[0] == '+' || std::isspace(static_cast<unsigned char>(text[0])))
    return false;
  char* end = nullptr;
  errno = 0;
  const unsigned long long v = std::strtoull(text.c_str(), &end, 0);
  if (errno != 0 || end != text.c_str() + text.size()) return false;
  out = v;
  return true;
}

bool parseIniDouble(const std::string& text, double& out) {
  if (text.empty() || std::isspace(static_cast<unsigned char>(text[0]))) return false;
  char* end = nullptr;
  errno = 0;
  const double v = std::strtod(text.c_str(), &end);
  if (errno != 0 || end != text.c_str() + text.size() || !std::isfinite(v)) return false;
  out = v;
  return true;
}

}  // namespace pamc::canopen
