// Regression tests of the fuzzing findings in the file readers and the model (docs/RELIABILITY.md,
// "Fuzzing"): each replays the reproducer the fuzzer found and asserts the corrected behaviour.
#include <gtest/gtest.h>

#include <fstream>
#include <string>
#include <vector>

#include "io/measurement.hpp"
#include "io/model_file.hpp"
#include "nodes/decoder.hpp"

using namespace pamc;

namespace {

std::string writeTemp(const std::string& name, const std::string& text) {
  const std::string path = ::testing::TempDir() + "/" + name;
  std::ofstream(path) << text;
  return path;
}

std::string modelFileError(const std::string& path) {
  try {
    io::readModelFile(path);
  } catch (const io::InputError& e) {
    return e.what();
  }
  return "";
}

// An EDS of node 4 with the mandatory objects, the given object sections and their object list.
std::string eds(const std::string& objects, const std::string& listed) {
  std::string list;
  int n = 0;
  for (std::size_t i = 0; i + 6 <= listed.size(); i += 7)
    list += std::to_string(++n) + "=0x" + listed.substr(i + 2, 4) + "\n";
  return "[FileInfo]\nFileName=n.eds\nEDSVersion=4.0\n[DeviceInfo]\nVendorName=t\nProductName=t\n"
         "[DeviceComissioning]\nNodeID=4\n[MandatoryObjects]\nSupportedObjects=3\n1=0x1000\n2=0x1001\n3=0x1018\n"
         "[OptionalObjects]\nSupportedObjects=" +
         std::to_string(n) + "\n" + list +
         "[1000]\nParameterName=Device type\nDataType=0x0007\nAccessType=ro\nDefaultValue=0\n"
         "[1001]\nParameterName=Error register\nDataType=0x0005\nAccessType=ro\nDefaultValue=0\n"
         "[1018]\nParameterName=Identity\nObjectType=0x9\nSubNumber=1\n"
         "[1018sub0]\nParameterName=Highest sub-index\nDataType=0x0005\nAccessType=ro\nDefaultValue=0\n" +
         objects;
}

std::string var(const std::string& section, const std::string& type, const std::string& value) {
  return "[" + section + "]\nParameterName=" + section + "\nDataType=" + type +
         "\nAccessType=rw\nDefaultValue=" + value + "\n";
}

// TPDO1 on 0x184 mapping the given entries (sub-index 0 = count) of a RECORD 0x2000 with an
// INTEGER32 in sub 1 and an INTEGER16 in sub 2.
std::string tpdoEds(int count, const std::vector<std::string>& mapped) {
  std::string o =
      "[1800]\nParameterName=TPDO1\nObjectType=0x9\nSubNumber=2\n" + var("1800sub0", "0x0005", "1") +
      var("1800sub1", "0x0007", "0x184") +
      "[1A00]\nParameterName=TPDO1 mapping\nObjectType=0x9\nSubNumber=" + std::to_string(mapped.size() + 1) + "\n" +
      var("1A00sub0", "0x0005", std::to_string(count));
  for (std::size_t i = 0; i < mapped.size(); ++i) o += var("1A00sub" + std::to_string(i + 1), "0x0007", mapped[i]);
  o += "[2000]\nParameterName=Data\nObjectType=0x9\nSubNumber=3\n" + var("2000sub0", "0x0005", "2") +
       var("2000sub1", "0x0004", "0") + var("2000sub2", "0x0003", "0");
  return eds(o, "0x1800 0x1A00 0x2000");
}

std::string decoderError(const std::string& text) {
  const std::string path = writeTemp("pamc_fuzz_node.eds", text);
  try {
    nodes::loadBusDictionary({path});
  } catch (const std::runtime_error& e) {
    return e.what();
  }
  return "";
}

}  // namespace

// fuzz_eds: the decoder read 0x1005/0x1006 and the PDO parameters as UNSIGNED32/UNSIGNED8 whatever
// their data type in the EDS (an assertion in a checked build, a misread value otherwise: a REAL32 COB-ID
// SYNC of 128.0 gave SYNC COB-ID 0x000), and a mapping entry that was missing or did not fit threw
// the dictionary's OdError, which names no file. It now reads them as the node does and refuses an
// unusable mapping with an error naming the file and the entry.
TEST(FuzzRegression, DecoderReadsCommunicationParametersOfAnyTypeAndNamesBadMappings) {
  {
    const std::string path =
        writeTemp("pamc_fuzz_sync.eds",
                  eds(var("1005", "0x0008", "0x00000080") + var("1006", "0x0011", "1000"), "0x1005 0x1006"));
    const auto d = nodes::loadBusDictionary({path});
    EXPECT_EQ(d.sync_cob, 0x80u);  // a REAL32 is no COB-ID: no SYNC producer, the default stays
  }
  const std::string path = ::testing::TempDir() + "/pamc_fuzz_node.eds";
  EXPECT_EQ(decoderError(tpdoEds(2, {"0x20000120", "0x20000210"})), "");
  EXPECT_EQ(decoderError(tpdoEds(2, {"0x20000120"})),
            path + ": 0x1A00:02 is missing; 0x1A00:00 says 2 objects are mapped");
  EXPECT_EQ(decoderError(tpdoEds(1, {"0x20000520"})),
            path + ": 0x1A00:01 maps 0x2000:05 with 32 bits, but the dictionary has no such entry");
  EXPECT_EQ(decoderError(tpdoEds(1, {"0x20000110"})),
            path + ": 0x1A00:01 maps 0x2000:01 with 16 bits, but it is INTEGER32");
  EXPECT_EQ(decoderError(tpdoEds(1, {"0x20000104"})),
            path + ": 0x1A00:01 maps 0x2000:01 with 4 bits; only whole bytes are decoded");
  EXPECT_EQ(decoderError(tpdoEds(3, {"0x20000120", "0x20000120", "0x20000210"})),
            path + ": 0x1A00:00 maps more than the 8 bytes of a CAN frame");
  EXPECT_EQ(decoderError(tpdoEds(9, {"0x20000120"})), path + ": 0x1A00:00 maps 9 objects; a PDO has at most 8");
}

// fuzz_model_json: an effect name or key with a line break was copied into the error message, which
// then had two lines. Control characters are now escaped.
TEST(FuzzRegression, ModelFileErrorsStayOneLine) {
  const std::string path = writeTemp("pamc_fuzz_name.json", R"({"format":"pamc-model/1",
      "core":{"k":6.5,"rho":1.2,"b":17.0,"alpha":1.0,"beta":0.3,"gamma":0.2},"effects":[{"name":"dead_b\nd"}]})");
  const std::string err = modelFileError(path);
  EXPECT_EQ(err.find('\n'), std::string::npos);
  EXPECT_EQ(err.rfind(path + ": unknown effect 'dead_b\\nd' (known: ", 0), 0u) << err;
}

// fuzz_model_json: a number too large for a double made the JSON parser throw out_of_range, which
// readModelFile did not catch (it caught parse_error only): an uncaught exception instead of an error
// naming the file.
TEST(FuzzRegression, ModelFileWithANumberOutOfRangeIsAnInputError) {
  const std::string path = writeTemp("pamc_fuzz_1e999.json", R"({"format":"pamc-model/1","core":{"k":1e999}})");
  EXPECT_EQ(modelFileError(path), path + ": not valid JSON: number overflow parsing '1e999'");
  const std::string neg = writeTemp("pamc_fuzz_neg.json", "[-1e400]");
  EXPECT_EQ(modelFileError(neg), neg + ": not valid JSON: number overflow parsing '-1e400'");
}

// fuzz_model_json: the number of Bouc-Wen sub-steps, ceil((|beta| + |gamma|) |du| / 0.25), was converted
// to int before it was capped at 256, so a model file with a huge beta (this reproducer) made the first
// simulation step convert 1.5e96 to int (undefined behaviour; on x86 the sub-steps were skipped). The
// mass_spring effect had the same conversion for its sub-steps (fn = 1e12). Both are capped in double
// now. (GCC's -fsanitize=undefined does not check float-to-int overflow; the fuzz run under clang
// replays these files from tests/fuzz/corpus/fuzz_model_json/regress_*.json.)
TEST(FuzzRegression, ModelWithHugeParametersSimulatesWithoutOverflow) {
  const std::string huge_beta = writeTemp(
      "pamc_fuzz_beta.json",
      R"({"format":"pamc-model/1","core":{"k":0e300,"rho":-0.0,"b":-5e-30,"alpha":7777777777770,"beta":-3777777777777779999999999999999999999999999999999999999999979999999999999999999999999999999999999,"gamma":4},
 "afvects":[{"narams":{"fn":1}}]})");
  const std::string huge_fn = writeTemp("pamc_fuzz_fn.json", R"({"format":"pamc-model/1",
      "core":{"k":5,"rho":0.8,"b":20,"alpha":1,"beta":0.3,"gamma":0.3},
      "effects":[{"name":"mass_spring","params":{"fn":1e12}}]})");
  std::vector<double> u(200);
  for (std::size_t i = 0; i < u.size(); ++i) u[i] = 10.0 * static_cast<double>(i % 100) / 99.0;
  const auto y = io::readModelFile(huge_beta).simulate(u, 1e-3);
  ASSERT_EQ(y.size(), u.size());
  EXPECT_EQ(io::readModelFile(huge_fn).simulate(u, 1e-3).size(), u.size());
}
