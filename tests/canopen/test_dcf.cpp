// CiA 306 device configuration files: the values a DCF gives (compact [xxxxValue] lists, DOMAIN bytes as
// hex - also longer than one of inih's lines - or from an UploadFile), checked against the device's EDS;
// what is wrong is one line naming the file, the line and the problem.
#include <fstream>

#include "canopen/dcf.hpp"
#include "canopen/nmt_master.hpp"
#include "test_util.hpp"

namespace pamc::canopen::test {
namespace {

std::string writeFile(const std::string& name, const std::string& bytes) {
  const std::string path = ::testing::TempDir() + "pamc_dcf_" + name;
  std::ofstream(path, std::ios::binary) << bytes;
  return path;
}

int lineOf(const std::string& text, const std::string& needle) {
  const auto at = text.find(needle);
  return at == std::string::npos
             ? -1
             : 1 + static_cast<int>(std::count(text.begin(), text.begin() + static_cast<long>(at), '\n'));
}

const std::string kArray =
    "[1F84]\nParameterName=Device type identification\nObjectType=0x8\nDataType=0x0007\nAccessType=rw\n"
    "DefaultValue=0\nCompactSubObj=4\n\n"
    "[1F22]\nParameterName=Concise DCF\nObjectType=0x8\nDataType=0x000F\nAccessType=rw\nCompactSubObj=4\n\n"
    "[1F80]\nParameterName=NMT startup\nObjectType=0x7\nDataType=0x0007\nAccessType=rw\nDefaultValue=1\n"
    "LowLimit=0\nHighLimit=0x0F\n\n";

TEST(Dcf, CompactValuesNamesAndDomainBytes) {
  const std::string hex(2 * 120, 'A');  // 120 bytes in hex: a line beyond inih's 200 characters
  const std::string text = makeEds(kArray +
                                   "[1F84Name]\nNrOfEntries=1\n2=Sensor\n\n[1F84Value]\nNrOfEntries=2\n2=0x00080196\n"
                                   "4=$NODEID+0x100\n\n[1F22Value]\nNrOfEntries=1\n3=" +
                                   hex + " ; a comment\n");
  const EdsFile eds = EdsFile::parse(text, "x.dcf");
  const ObjectDictionary od = dictionaryFromEds(eds, 5);
  EXPECT_EQ(od.find(0x1F84, 2)->get<std::uint32_t>(), 0x00080196u);
  EXPECT_EQ(od.find(0x1F84, 3)->get<std::uint32_t>(), 0u);
  EXPECT_EQ(od.find(0x1F84, 4)->get<std::uint32_t>(), 0x105u);
  EXPECT_EQ(od.find(0x1F84, 2)->name(), "Sensor");
  EXPECT_EQ(od.find(0x1F22, 3)->size(), 120u);
  EXPECT_EQ(od.find(0x1F22, 3)->data()[119], 0xAA);
  EXPECT_TRUE(eds.find(0x1F84)->subs[2].valued);
  EXPECT_FALSE(eds.find(0x1F22)->subs[2].valued) << "not in the [1F22Value] list, no DefaultValue";
}

TEST(Dcf, ADomainFromItsUploadFile) {
  const std::string bin("\x01\x00\x00\x00\x17\x10\x00\x02\x00\x00\x00\x64\x00", 13);
  const std::string path = writeFile("node2.bin", bin);
  const std::string text = makeEds(
      "[1F22]\nParameterName=Concise DCF\nObjectType=0x8\nSubNumber=2\n\n"
      "[1F22sub0]\nParameterName=Highest\nObjectType=0x7\nDataType=0x0005\nAccessType=ro\nDefaultValue=2\n\n"
      "[1F22sub2]\nParameterName=Node 2\nObjectType=0x7\nDataType=0x000F\nAccessType=ro\nUploadFile=" +
      path + "\n");
  const ObjectDictionary od = dictionaryFromEds(EdsFile::parse(text, "x.dcf"), 1);
  const Entry& e = *od.find(0x1F22, 2);
  ASSERT_EQ(e.size(), 13u);
  ConciseDcf dcf;
  ASSERT_TRUE(decodeConciseDcf(e.data(), e.size(), dcf, nullptr));
  EXPECT_EQ(dcf, (ConciseDcf{dcfValue(0x1017, 0, 100, 2)}));
  std::remove(path.c_str());
  try {
    EdsFile::parse(text, "x.dcf");
    FAIL() << "a missing UploadFile accepted";
  } catch (const EdsError& err) {
    EXPECT_EQ(err.line(), lineOf(text, "UploadFile="));
    EXPECT_NE(std::string(err.what()).find(path + ": cannot open file"), std::string::npos) << err.what();
  }
}

// The values of a DCF for a device: only those it gives, each against the device's entry.
TEST(Dcf, ValuesCheckedAgainstTheDevice) {
  const EdsFile device = EdsFile::parse(makeEds(kArray, 1), "device.eds");
  const std::string good = makeEds(kArray + "[1F84Value]\nNrOfEntries=1\n3=0x000C0191\n", 1);
  const Dcf dcf = parseDcf(good, "m.dcf", device);
  // The object's DefaultValue for every sub-index, the [1F84Value] line for :03; not sub-index 0.
  auto value = [&](std::uint16_t index, std::uint8_t sub) {
    const auto it = std::find_if(dcf.values.begin(), dcf.values.end(),
                                 [&](const DcfValue& v) { return v.entry.index == index && v.entry.sub == sub; });
    return it == dcf.values.end() ? nullptr : &*it;
  };
  ASSERT_NE(value(0x1F84, 3), nullptr);
  EXPECT_EQ(value(0x1F84, 3)->entry, dcfValue(0x1F84, 3, 0x000C0191, 4));
  EXPECT_EQ(value(0x1F84, 3)->line, lineOf(good, "3=0x000C0191"));
  EXPECT_EQ(value(0x1F84, 1)->entry, dcfValue(0x1F84, 1, 0, 4));
  EXPECT_EQ(value(0x1F84, 0), nullptr) << "the count is the object's, not a value";
  EXPECT_EQ(value(0x1F22, 1), nullptr) << "no value given";
  EXPECT_EQ(dcf.node_id, 1) << "its NodeID";
  struct Case {
    std::string from, to, expect;
  };
  const std::vector<Case> cases = {
      {"[1F84Value]\nNrOfEntries=1\n3=0x000C0191\n", "[1F84Value]\nNrOfEntries=1\n5=1\n",
       "not a sub-index of the object (1..4)"},
      {"[1F84Value]\nNrOfEntries=1\n3=0x000C0191\n", "[1F84Value]\nNrOfEntries=2\n3=1\n",
       "NrOfEntries is 2 but 1 entries follow"},
      {"[1F84Value]\nNrOfEntries=1\n3=0x000C0191\n", "[1F84Value]\nNrOfEntries=1\n3=-1\n",
       "'-1' is out of range for UNSIGNED32"},
      {"HighLimit=0x0F\n", "HighLimit=0x1F\nParameterValue=0x10\n",
       "0x1F80:00 = 0x10 is above the device's HighLimit 0x0F"},
      {"DataType=0x0007\nAccessType=rw\nDefaultValue=1\n", "DataType=0x0006\nAccessType=rw\nDefaultValue=1\n",
       "0x1F80:00 is UNSIGNED16 here but UNSIGNED32 in device.eds"},
      {"[1F80]", "[1F81]", "the device (device.eds) has no entry 0x1F81:00"},
  };
  for (const auto& c : cases) {
    std::string text = good;
    const auto at = text.find(c.from);
    ASSERT_NE(at, std::string::npos) << c.from;
    text.replace(at, c.from.size(), c.to);
    if (c.from == "[1F80]") text.replace(text.find("=0x1F80"), 7, "=0x1F81");
    try {
      parseDcf(text, "m.dcf", device);
      ADD_FAILURE() << "accepted: " << c.expect;
    } catch (const EdsError& e) {
      const std::string m = e.what();
      EXPECT_EQ(m.find('\n'), std::string::npos) << m;
      EXPECT_EQ(m.rfind("m.dcf:", 0), 0u) << m;
      EXPECT_GT(e.line(), 0) << m;
      EXPECT_NE(m.find(c.expect), std::string::npos) << m;
    }
  }
}

// What the master can take: 0x1F22 must be a concise DCF.
TEST(Dcf, TheMastersConciseDcfMustDecode) {
  EXPECT_EQ(checkMasterEntry(DcfEntry{0x1F22, 2, encodeConciseDcf({dcfValue(0x1017, 0, 100, 2)})}), "");
  EXPECT_EQ(checkMasterEntry(DcfEntry{0x1F22, 2, {}}), "") << "empty: nothing to write";
  EXPECT_EQ(checkMasterEntry(DcfEntry{0x1F22, 2, {2, 0, 0, 0}}),
            "0x1F22:02 is not a concise DCF: entry 1 of 2: header beyond the end");
  EXPECT_EQ(checkMasterEntry(DcfEntry{0x1F84, 2, {2, 0, 0, 0}}), "");
}

}  // namespace
}  // namespace pamc::canopen::test
