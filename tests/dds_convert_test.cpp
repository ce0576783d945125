// ResolvedBlock / Diagnostic / ParseSummary <-> IDL types, through real CDR serialization:
// every field must come back bit for bit, and corrupt enumerations must be refused.
#include <gtest/gtest.h>

#include <cstring>
#include <random>

#include "dds_convert.hpp"
#include "gcpipePubSubTypes.h"

namespace gcpipe {
namespace {

// A block with every field set to a random value (enumerations among their valid values), so a
// field that the conversion forgets comes back different.
ResolvedBlock random_block(std::mt19937_64& rng) {
  std::uniform_real_distribution<double> u(-1e4, 1e4);
  std::uniform_int_distribution<int> i(-100000, 100000);
  auto pick = [&rng](std::initializer_list<int> values) {
    return *(values.begin() + std::uniform_int_distribution<std::size_t>(0, values.size() - 1)(rng));
  };
  auto axes = [&] {
    Axes a;
    for (double& v : a) v = u(rng);
    return a;
  };
  auto vec = [&] {
    Vec3 a;
    for (double& v : a) v = u(rng);
    return a;
  };
  ResolvedBlock b;
  b.line = rng();
  b.text = "N" + std::to_string(rng() % 100000) + " G1 X" + std::to_string(u(rng)) + " (é ü)";
  b.comment = std::string(rng() % 40, 'c') + " | second";
  b.motion = static_cast<Motion>(pick({0, 1, 2, 3, 4, 5, 6}));
  b.start = axes();
  b.target = axes();
  b.axis_words = static_cast<std::uint8_t>(rng() % 32);
  b.plane = static_cast<Plane>(pick({17, 18, 19}));
  b.centre = vec();
  b.radius = u(rng);
  b.turns = i(rng);
  b.feed = u(rng);
  b.feed_mode = static_cast<FeedMode>(pick({93, 94}));
  b.dwell = u(rng);
  b.spindle_speed = u(rng);
  b.spindle = static_cast<Spindle>(pick({3, 4, 5}));
  b.tool = i(rng);
  b.tool_in_spindle = i(rng);
  b.tool_length_offset = i(rng);
  b.tool_length = u(rng);
  b.tool_length_active = rng() & 1;
  b.tcp = rng() & 1;
  b.coolant = static_cast<std::uint8_t>(rng() % 4);
  b.work_offset = pick({54, 55, 56, 57, 58, 59});
  b.work_origin = axes();
  b.source_units = static_cast<Units>(pick({20, 21}));
  b.tool_change = rng() & 1;
  b.stop = static_cast<ProgramStop>(pick({0, 1, 2, 3, 4}));
  b.program_number = i(rng);
  b.percent = rng() & 1;
  b.slot.start = vec();
  b.slot.end = vec();
  b.slot.bottom = u(rng);
  b.slot.clearance = u(rng);
  b.slot.width = u(rng);
  b.slot.step = u(rng);
  b.slot.depth_step = u(rng);
  b.slot.tool_diameter = u(rng);
  b.slot.climb = rng() & 1;
  return b;
}

template <std::size_t N>
bool bits_equal(const std::array<double, N>& a, const std::array<double, N>& b) {
  return std::memcmp(a.data(), b.data(), sizeof(double) * N) == 0;
}
bool bits_equal(double a, double b) { return std::memcmp(&a, &b, sizeof a) == 0; }

// Field by field, doubles compared bit for bit (same_meaning() ignores line and text).
void expect_identical(const ResolvedBlock& a, const ResolvedBlock& b) {
#define SAME(f) EXPECT_TRUE(a.f == b.f) << #f
#define SAME_BITS(f) EXPECT_TRUE(bits_equal(a.f, b.f)) << #f
  SAME(line); SAME(text); SAME(comment); SAME(motion); SAME_BITS(start); SAME_BITS(target);
  SAME(axis_words); SAME(plane); SAME_BITS(centre); SAME_BITS(radius); SAME(turns);
  SAME_BITS(feed); SAME(feed_mode); SAME_BITS(dwell); SAME_BITS(spindle_speed); SAME(spindle);
  SAME(tool); SAME(tool_in_spindle); SAME(tool_length_offset); SAME_BITS(tool_length);
  SAME(tool_length_active); SAME(tcp); SAME(coolant); SAME(work_offset); SAME_BITS(work_origin);
  SAME(source_units); SAME(tool_change); SAME(stop); SAME(program_number); SAME(percent);
  SAME_BITS(slot.start); SAME_BITS(slot.end); SAME_BITS(slot.bottom); SAME_BITS(slot.clearance);
  SAME_BITS(slot.width); SAME_BITS(slot.step); SAME_BITS(slot.depth_step);
  SAME_BITS(slot.tool_diameter); SAME(slot.climb);
#undef SAME
#undef SAME_BITS
}

// Serializes with the generated type support, as a DataWriter does, and reads it back.
msg::BlockBatch through_cdr(msg::BlockBatch& batch) {
  msg::BlockBatchPubSubType type;
  eprosima::fastrtps::rtps::SerializedPayload_t payload(type.getSerializedSizeProvider(&batch)());
  EXPECT_TRUE(type.serialize(&batch, &payload));
  msg::BlockBatch back;
  EXPECT_TRUE(type.deserialize(&payload, &back));
  return back;
}

TEST(DdsConvert, BlocksAndDiagnosticsSurviveCdrBitForBit) {
  std::mt19937_64 rng(20261121);
  msg::BlockBatch batch;
  std::vector<ResolvedBlock> blocks;
  std::vector<Diagnostic> diags;
  for (int k = 0; k < 500; ++k) {
    blocks.push_back(random_block(rng));
    dds::to_msg(blocks.back(), batch.blocks().emplace_back());
    Diagnostic d{"dir/prog.nc", rng(), static_cast<std::uint32_t>(rng()),
                 static_cast<Severity>(rng() % 3), "word X appears twice (X1. at column 4)"};
    diags.push_back(d);
    dds::to_msg(d, k % 2 ? LineStatus::kRejected : LineStatus::kDeleted,
                batch.diagnostics().emplace_back());
  }
  const msg::BlockBatch back = through_cdr(batch);
  ASSERT_EQ(back.blocks().size(), blocks.size());
  ASSERT_EQ(back.diagnostics().size(), diags.size());
  for (std::size_t k = 0; k < blocks.size(); ++k) {
    ResolvedBlock b;
    std::string why;
    ASSERT_TRUE(dds::from_msg(back.blocks()[k], b, &why)) << why;
    expect_identical(blocks[k], b);
    Diagnostic d;
    LineStatus st{};
    ASSERT_TRUE(dds::from_msg(back.diagnostics()[k], d, st, &why)) << why;
    EXPECT_EQ(d.file, diags[k].file);
    EXPECT_EQ(d.line, diags[k].line);
    EXPECT_EQ(d.column, diags[k].column);
    EXPECT_EQ(d.severity, diags[k].severity);
    EXPECT_EQ(d.message, diags[k].message);
    EXPECT_EQ(st, k % 2 ? LineStatus::kRejected : LineStatus::kDeleted);
  }
}

TEST(DdsConvert, ResolvedBlockLayoutIsTheOneMirroredInTheIdl) {
  // A tripwire: a field added to ResolvedBlock changes its size. Mirror it in idl/gcpipe.idl
  // (struct Block), in dds_convert.cpp and in random_block()/expect_identical() above, then
  // update this number.
  EXPECT_EQ(sizeof(ResolvedBlock), 432u);
}

TEST(DdsConvert, SummaryRoundTripsAndCountsAreChecked) {
  ParseSummary s{1000, 900, 60, 40, 123456};
  msg::ParseCounts c;
  dds::to_msg(s, c);
  const ParseSummary r = dds::from_msg(c);
  EXPECT_EQ(r.lines_read, 1000u);
  EXPECT_EQ(r.blocks_emitted, 900u);
  EXPECT_EQ(r.lines_rejected, 60u);
  EXPECT_EQ(r.lines_deleted, 40u);
  EXPECT_EQ(r.bytes_read, 123456u);
  EXPECT_EQ(dds::check_counts(s, 900, 60, 40), "");
  EXPECT_NE(dds::check_counts(s, 899, 60, 40).find("received 899 blocks"), std::string::npos);
  EXPECT_NE(dds::check_counts(s, 900, 59, 40).find("rejected"), std::string::npos);
  EXPECT_NE(dds::check_counts(s, 900, 60, 41).find("deleted"), std::string::npos);
  ParseSummary bad = s;
  bad.lines_read = 1001;
  EXPECT_NE(dds::check_counts(bad, 900, 60, 40).find("do not add up"), std::string::npos);
}

TEST(DdsConvert, CorruptEnumerationsAreRefusedByName) {
  std::mt19937_64 rng(7);
  msg::Block m;
  dds::to_msg(random_block(rng), m);
  ResolvedBlock b;
  std::string why;
  msg::Block bad = m;
  bad.motion(7);
  EXPECT_FALSE(dds::from_msg(bad, b, &why));
  EXPECT_NE(why.find("'motion' holds 7"), std::string::npos) << why;
  bad = m;
  bad.plane(20);
  EXPECT_FALSE(dds::from_msg(bad, b, &why));
  EXPECT_NE(why.find("'plane'"), std::string::npos) << why;
  bad = m;
  bad.feed_mode(95);
  EXPECT_FALSE(dds::from_msg(bad, b, &why));
  bad = m;
  bad.spindle(6);
  EXPECT_FALSE(dds::from_msg(bad, b, &why));
  bad = m;
  bad.source_units(22);
  EXPECT_FALSE(dds::from_msg(bad, b, &why));
  bad = m;
  bad.stop(5);
  EXPECT_FALSE(dds::from_msg(bad, b, &why));
  bad = m;
  bad.coolant(4);
  EXPECT_FALSE(dds::from_msg(bad, b, &why));
  bad = m;
  bad.axis_words(32);
  EXPECT_FALSE(dds::from_msg(bad, b, &why));
  EXPECT_TRUE(dds::from_msg(m, b, &why)) << why;

  msg::LineDiagnostic d;
  dds::to_msg(Diagnostic{"f", 1, 2, Severity::kError, "m"}, LineStatus::kRejected, d);
  Diagnostic out;
  LineStatus st{};
  d.line_status(static_cast<std::uint8_t>(LineStatus::kBlock));
  EXPECT_FALSE(dds::from_msg(d, out, st, &why));
  EXPECT_NE(why.find("line_status"), std::string::npos);
  d.line_status(static_cast<std::uint8_t>(LineStatus::kDeleted));
  d.severity(3);
  EXPECT_FALSE(dds::from_msg(d, out, st, &why));
  EXPECT_NE(why.find("severity"), std::string::npos);
}

}  // namespace
}  // namespace gcpipe
