#pragma once
// INI files as CiA 306 (EDS, DCF) and pamc's rig files write them, read with inih: sections with
// "key = value" lines, ';' comments, names case-insensitive. Every section and key keeps its line, so
// whoever interprets the values can name the line of a bad one.
#include <cstdint>
#include <stdexcept>
#include <string>
#include <vector>

namespace pamc::canopen {

// "file:line: problem" (line 0: the file as a whole).
class IniError : public std::runtime_error {
 public:
  IniError(const std::string& file, int line, const std::string& problem);
  const std::string& file() const { return file_; }
  int line() const { return line_; }
  const std::string& problem() const { return problem_; }  // without "file:line: "

 private:
  std::string file_;
  int line_;
  std::string problem_;
};

struct IniKey {
  std::string name;   // as written
  std::string value;  // trimmed, inline comment removed
  int line = 0;
};

struct IniSection {
  std::string name;
  int line = 0;
  std::vector<IniKey> keys;
  const IniKey* find(const std::string& key) const;  // case-insensitive
};

struct IniFile {
  std::string path;
  std::vector<IniSection> sections;
  const IniSection* find(const std::string& section) const;  // case-insensitive
};

// Throws IniError: missing file, a key outside any section, a duplicate section or key, a line inih
// cannot parse.
IniFile readIni(const std::string& path);
IniFile parseIni(const std::string& text, const std::string& path);

// Numbers as EDS and rig files write them: decimal or 0x-hex, nothing after the number.
bool parseIniUnsigned(const std::string& text, std::uint64_t& out);
bool parseIniDouble(const std::string& text, double& out);

}  // namespace pamc::canopen
