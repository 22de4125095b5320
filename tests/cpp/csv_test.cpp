// The CSV tokenizer of the text readers (util/csv.h): RFC 4180 quoting, a UTF-8 byte-order mark,
// comment and blank lines, line numbers, and one error naming the file and line for the rest.
#include "aos/util/csv.h"

#include <string>
#include <vector>

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include "error_of.h"

namespace aos {
namespace {

using ::testing::ElementsAre;
using ::testing::HasSubstr;
using test_util::ErrorOf;

TEST(Csv, PlainFieldsAreTrimmedAndCommentsAndBlankLinesSkipped) {
  const std::vector<CsvRecord> records =
      ParseCsv("# comment\nname , x,y\r\n\n   \n  # indented comment\na.png,1, 2 \r\nb,,\n", "p.csv");
  ASSERT_EQ(records.size(), 3u);
  EXPECT_EQ(records[0].line, 2);
  EXPECT_THAT(records[0].fields, ElementsAre("name", "x", "y"));
  EXPECT_EQ(records[1].line, 6);
  EXPECT_THAT(records[1].fields, ElementsAre("a.png", "1", "2"));
  EXPECT_EQ(records[2].line, 7);
  EXPECT_THAT(records[2].fields, ElementsAre("b", "", ""));  // a trailing comma: an empty field
  // No line break at the end.
  EXPECT_THAT(ParseCsv("a,b", "p.csv")[0].fields, ElementsAre("a", "b"));
  EXPECT_TRUE(ParseCsv("", "p.csv").empty());
}

TEST(Csv, AByteOrderMarkAtTheStartIsSkipped) {
  const std::vector<CsvRecord> records = ParseCsv("\xEF\xBB\xBFname,x\na,1\n", "p.csv");
  ASSERT_EQ(records.size(), 2u);
  EXPECT_THAT(records[0].fields, ElementsAre("name", "x"));  // not "\xEF\xBB\xBFname"
  // Only at the start: elsewhere it is text (U+FEFF is valid UTF-8).
  EXPECT_THAT(ParseCsv("a,\xEF\xBB\xBF" "b\n", "p.csv")[0].fields,
              ElementsAre("a", "\xEF\xBB\xBF" "b"));
}

TEST(Csv, QuotedFieldsHoldCommasQuotesAndLineBreaks) {
  const std::vector<CsvRecord> records = ParseCsv(
      "\"name\",\"x\"\n"
      "\"a,b.png\", \"1\" \n"
      "\"say \"\"hi\"\".png\",2\r\n"
      "\" padded \",\"\"\n"
      "\"two\nlines\",3\n"
      "\"#not a comment\",4\n",
      "p.csv");
  ASSERT_EQ(records.size(), 6u);
  EXPECT_THAT(records[0].fields, ElementsAre("name", "x"));
  EXPECT_THAT(records[1].fields, ElementsAre("a,b.png", "1"));
  EXPECT_THAT(records[2].fields, ElementsAre("say \"hi\".png", "2"));
  EXPECT_THAT(records[3].fields, ElementsAre(" padded ", ""));
  EXPECT_EQ(records[4].line, 5);
  EXPECT_THAT(records[4].fields, ElementsAre("two\nlines", "3"));
  EXPECT_EQ(records[5].line, 7);  // the record with a line break took two lines
  EXPECT_THAT(records[5].fields, ElementsAre("#not a comment", "4"));
}

TEST(Csv, MalformedQuotingIsOneErrorNamingFileAndLine) {
  EXPECT_THAT(ErrorOf([] { ParseCsv("a,b\n\"open,1\n2,3\n", "p.csv"); }),
              HasSubstr("p.csv: line 2: field 1: its opening quote is never closed"));
  EXPECT_THAT(ErrorOf([] { ParseCsv("a,b\nx,\"y\"z\n", "p.csv"); }),
              HasSubstr("p.csv: line 2: field 2: text after its closing quote"));
  EXPECT_THAT(ErrorOf([] { ParseCsv("a,b\nx,y\"z\n", "p.csv"); }),
              HasSubstr("p.csv: line 2: field 2: a quote inside an unquoted field"));
  EXPECT_THAT(ErrorOf([] { ParseCsv("a,b\nx,\xFF\n", "p.csv"); }),
              HasSubstr("p.csv: line 2: not valid UTF-8 text"));
}

TEST(Csv, AFieldWrittenByCsvFieldReadsBackAsItWas) {
  const std::vector<std::string> fields = {"plain", "a,b", "say \"hi\"", "two\nlines",
                                           " padded ", "", "frame_001.png"};
  std::string line;
  for (size_t k = 0; k < fields.size(); ++k) line += (k ? "," : "") + CsvField(fields[k]);
  EXPECT_EQ(CsvField("plain"), "plain");  // quoted only where needed
  const std::vector<CsvRecord> records = ParseCsv(line + "\n", "f.csv");
  ASSERT_EQ(records.size(), 1u);
  EXPECT_EQ(records[0].fields, fields);
}

}  // namespace
}  // namespace aos
