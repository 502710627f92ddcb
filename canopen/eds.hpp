// EDS parser (CiA 306 electronic data sheet, INI format read with inih).
#pragma once

#include <cstdint>
#include <map>
#include <stdexcept>
#include <string>
#include <string_view>
#include <vector>

#include "canopen/od.hpp"

namespace pamc::canopen {

// A syntax or semantic error in an EDS file. what() reads "file:line: [section] problem".
class EdsError : public std::runtime_error {
 public:
  EdsError(std::string file, int line, std::string section, std::string problem);
  const std::string& file() const { return file_; }
  int line() const { return line_; }  // 0 if the problem has no single line (e.g. a missing section)
  const std::string& section() const { return section_; }
  const std::string& problem() const { return problem_; }

 private:
  std::string file_;
  int line_;
  std::string section_;
  std::string problem_;
};

struct EdsSubObject {
  std::uint8_t sub_index = 0;
  std::string section;  // e.g. "1600sub1", or "1017" for a VAR
  int line = 0;         // line of the section header
  std::string name;
  DataType data_type = DataType::Unsigned8;
  Access access = Access::ReadOnly;
  bool pdo_mapping = false;
  std::string default_value;  // raw EDS text, may contain $NODEID (DOMAIN: hex bytes, also from a file)
  int default_line = 0;
  // The file gives this entry a value: ParameterValue, DefaultValue, UploadFile / DownloadFile (DOMAIN)
  // or a line of the object's [xxxxValue] section. A DCF applies only these (canopen/dcf.hpp).
  bool valued = false;
  std::string low_limit;
  int low_line = 0;
  std::string high_limit;
  int high_line = 0;
};

struct EdsObject {
  std::uint16_t index = 0;
  std::string name;
  ObjectType object_type = ObjectType::Var;
  int line = 0;
  std::vector<EdsSubObject> subs;  // a VAR has exactly one, with sub_index 0
};

class EdsFile {
 public:
  // Reads and checks a file; throws EdsError naming the file, line and problem.
  static EdsFile load(const std::string& path);
  // Same for text already in memory; name is used in error messages.
  static EdsFile parse(const std::string& text, const std::string& name);

  const EdsObject* find(std::uint16_t index) const;

  std::string file;
  std::map<std::string, std::string> file_info;    // [FileInfo], keys lower-case
  std::map<std::string, std::string> device_info;  // [DeviceInfo], keys lower-case
  std::uint8_t node_id = 0;                        // [DeviceComissioning] NodeID, 0 if absent
  std::vector<EdsObject> objects;                  // sorted by index
};

// Encodes an EDS value (DefaultValue, LowLimit, HighLimit) as little-endian bytes of the data type.
// Integers: decimal, 0x hex or leading-0 octal (CiA 306), optionally "$NODEID+<n>"; reals: decimal;
// VISIBLE_STRING: the text; OCTET_STRING/DOMAIN: hex digits. Returns "" or a description of the problem.
std::string encodeEdsValue(std::string_view text, DataType type, std::uint8_t node_id, std::vector<std::uint8_t>& out);

}  // namespace pamc::canopen
