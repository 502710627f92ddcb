// fuzz_candump: candump -l log text through readCandumpLog (strict: the first bad line is an error,
// except a last line without its newline, which a writer cut off: ignored with a warning),
// and the lines it can parse through the decoder (decodeCandump with the rig's od/*.eds dictionary),
// as `pamc decode` runs them.
// Documented error: std::runtime_error "name:line: problem". Properties: every parsed record prints
// back (formatCandumpLine) to a line that parses to the same record; decoded rows have one value per
// column and an increasing time.
#include <cmath>
#include <cstdint>
#include <sstream>
#include <string>
#include <string_view>
#include <vector>

#include "canopen/candump_log.hpp"
#include "fuzz_util.hpp"
#include "nodes/decoder.hpp"

using namespace pamc::canopen;
using pamc::fuzz::finding;

namespace {

const pamc::nodes::BusDictionary& rigDictionary() {
  static const pamc::nodes::BusDictionary dict = pamc::nodes::loadBusDictionary({PAMC_OD_DIR});
  return dict;
}

bool sameRecord(const CandumpRecord& a, const CandumpRecord& b) {
  return a.unix_time_us == b.unix_time_us && a.interface == b.interface && a.frame == b.frame &&
         a.frame.len == b.frame.len;
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string text(reinterpret_cast<const char*>(data), size);
  {
    std::istringstream in(text);
    try {
      const std::vector<CandumpRecord> log = readCandumpLog(in, "fuzz.log");
      (void)log;
    } catch (const std::runtime_error& e) {
      pamc::fuzz::checkMessage(e.what(), "fuzz.log:");
    }
  }

  // Every line that parses, for the round trip and the decoder.
  std::vector<CandumpRecord> records;
  std::size_t pos = 0;
  while (pos < text.size()) {
    std::size_t nl = text.find('\n', pos);
    if (nl == std::string::npos) nl = text.size();
    const std::string_view line(text.data() + pos, nl - pos);
    pos = nl + 1;
    CandumpRecord r;
    std::string err;
    if (!parseCandumpLine(line, r, &err)) {
      if (err.empty()) finding("parseCandumpLine failed without a reason");
      continue;
    }
    const std::string printed = formatCandumpLine(r.frame, r.unix_time_us, r.interface);
    CandumpRecord back;
    if (!parseCandumpLine(printed, back, &err)) finding("printed line does not parse: " + printed + ": " + err);
    if (!sameRecord(r, back)) finding("record changes on a round trip: " + std::string(line) + " -> " + printed);
    records.push_back(std::move(r));
  }

  const pamc::nodes::DecodedRun run = pamc::nodes::decodeCandump(records, rigDictionary());
  if (run.frames != records.size()) finding("decoder counted another number of frames");
  if (run.columns.size() < 3 || run.columns[0] != "t") finding("decoder columns do not start with t");
  for (std::size_t i = 0; i < run.rows.size(); ++i) {
    if (run.rows[i].size() != run.columns.size()) finding("decoded row with a wrong number of values");
    if (i > 0 && !(run.rows[i][0] > run.rows[i - 1][0])) finding("decoded time does not increase");
  }
  return 0;
}
