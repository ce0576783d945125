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
  b.path_tolerance = u(rng);
  b.path_mode = static_cast<PathMode>(pick({0, 1, 2}));
  b.spindle = static_cast<Spindle>(pick({3, 4, 5}));
  b.tool = i(rng);
  b.tool_in_spindle = i(rng);
  b.tool_length_offset = i(rng);
  b.tool_length = u(rng);
  b.tool_length_active = rng() & 1;
  b.tcp = rng() & 1;
  b.tool_vector = vec();
  b.tool_vector_mode = rng() & 1;
  b.coolant = static_cast<std::uint8_t>(rng() % 4);
  b.work_offset = pick({54, 55, 56, 57, 58, 59});
  b.work_origin = axes();
  b.source_units = static_cast<Units>(pick({20, 21}));
  b.tool_change = rng() & 1;
  b.stop = static_cast<ProgramStop>(pick({0, 1, 2, 3, 4}));
  b.program_number = i(rng);
  b.percent = rng() & 1;
  b.frame.origin = axes();
  b.frame.code = static_cast<FrameCode>(rng() % 15);
  b.frame.words = static_cast<std::uint8_t>(rng() % 32);
  b.frame.incremental = rng() & 1;
  b.frame.intermediate = rng() & 1;
  b.frame.selects_work_offset = rng() & 1;
  b.frame.sets_tool_length = rng() & 1;
  b.frame.has_r = rng() & 1;
  b.frame.p = i(rng);
  b.frame.values = axes();
  b.frame.r = u(rng);
  b.frame.resolved = axes();
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
  SAME_BITS(feed); SAME(feed_mode); SAME_BITS(dwell); SAME_BITS(spindle_speed); SAME_BITS(path_tolerance); SAME(path_mode); SAME(spindle);
  SAME(tool); SAME(tool_in_spindle); SAME(tool_length_offset); SAME_BITS(tool_length);
  SAME(tool_length_active); SAME(tcp); SAME_BITS(tool_vector);
  SAME(tool_vector_mode); SAME(coolant); SAME(work_offset); SAME_BITS(work_origin);
  SAME(source_units); SAME(tool_change); SAME(stop); SAME(program_number); SAME(percent);
  SAME_BITS(slot.start); SAME_BITS(slot.end); SAME_BITS(slot.bottom); SAME_BITS(slot.clearance);
  SAME_BITS(slot.width); SAME_BITS(slot.step); SAME_BITS(slot.depth_step);
  SAME_BITS(slot.tool_diameter); SAME(slot.climb);
  SAME_BITS(frame.origin); SAME(frame.code); SAME(frame.words); SAME(frame.incremental); SAME(frame.intermediate);
  SAME(frame.selects_work_offset); SAME(frame.sets_tool_length); SAME(frame.has_r); SAME(frame.p);
  SAME_BITS(frame.values); SAME_BITS(frame.r); SAME_BITS(frame.resolved);
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
    dds::to_msg(d, static_cast<dds::DiagnosticKind>(1 + k % 3), batch.diagnostics().emplace_back());
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
    dds::DiagnosticKind st{};
    ASSERT_TRUE(dds::from_msg(back.diagnostics()[k], d, st, &why)) << why;
    EXPECT_EQ(d.file, diags[k].file);
    EXPECT_EQ(d.line, diags[k].line);
    EXPECT_EQ(d.column, diags[k].column);
    EXPECT_EQ(d.severity, diags[k].severity);
    EXPECT_EQ(d.message, diags[k].message);
    EXPECT_EQ(st, static_cast<dds::DiagnosticKind>(1 + k % 3));
  }
}

TEST(DdsConvert, ResolvedBlockLayoutIsTheOneMirroredInTheIdl) {
  // A tripwire: a field added to ResolvedBlock changes its size. Mirror it in idl/gcpipe.idl
  // (struct Block), in dds_convert.cpp and in random_block()/expect_identical() above, then
  // update this number.
  EXPECT_EQ(sizeof(ResolvedBlock), 616u);
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
  EXPECT_EQ(dds::kind_of(LineStatus::kRejected), dds::DiagnosticKind::kLineRejected);
  EXPECT_EQ(dds::kind_of(LineStatus::kDeleted), dds::DiagnosticKind::kLineDeleted);
}

// The end marker's totals travel through CDR, and check_counts catches each kind of loss on an
// edge: the parse node's edge (blocks = parsed blocks) and the trochoid node's (one cycle became
// 20,000 blocks, another was rejected: one diagnostic of kind 3 and its skip moves).
TEST(DdsConvert, EndMarkerTotalsRoundTripAndEveryEdgeIsChecked) {
  dds::BatchTotals t;
  t.summary = ParseSummary{1000, 900, 60, 40, 123456};
  t.blocks_sent = 900 - 2 + 20000 + 3;
  t.diagnostics_sent = 60 + 40 + 1;
  t.blocks_rejected = 1;
  msg::BlockBatch m;
  dds::set_totals(t, m);
  const dds::BatchTotals r = dds::totals_of(through_cdr(m));
  EXPECT_EQ(r.summary.lines_read, 1000u);
  EXPECT_EQ(r.summary.blocks_emitted, 900u);
  EXPECT_EQ(r.summary.lines_rejected, 60u);
  EXPECT_EQ(r.summary.lines_deleted, 40u);
  EXPECT_EQ(r.summary.bytes_read, 123456u);
  EXPECT_EQ(r.blocks_sent, t.blocks_sent);
  EXPECT_EQ(r.diagnostics_sent, 101u);
  EXPECT_EQ(r.blocks_rejected, 1u);
  EXPECT_FALSE(r.stopped);

  dds::BatchArrivals got;
  got.blocks = t.blocks_sent;
  got.lines_rejected = 60;
  got.lines_deleted = 40;
  got.blocks_rejected = 1;
  EXPECT_EQ(got.diagnostics(), 101u);
  EXPECT_EQ(dds::check_counts(r, got), "");
  auto with = [&](auto change) {
    dds::BatchArrivals g = got;
    change(g);
    return dds::check_counts(r, g);
  };
  EXPECT_NE(with([](auto& g) { --g.blocks; }).find("received 20900 blocks but the upstream sent 20901"),
            std::string::npos);
  EXPECT_NE(with([](auto& g) { --g.lines_rejected; }).find("rejected-line"), std::string::npos);
  EXPECT_NE(with([](auto& g) { --g.lines_deleted; }).find("block-delete"), std::string::npos);
  EXPECT_NE(with([](auto& g) { --g.blocks_rejected; }).find("rejected-block"), std::string::npos);
  // A diagnostic of one kind arriving as another: totals agree, the kinds do not.
  EXPECT_NE(with([](auto& g) { --g.lines_deleted; ++g.blocks_rejected; }), "");
  dds::BatchTotals bad = r;
  bad.summary.lines_read = 1001;
  EXPECT_NE(dds::check_counts(bad, got).find("do not add up"), std::string::npos);
  // Strict mode stopped downstream of the parser: its later diagnostics were not forwarded.
  dds::BatchTotals stopped = r;
  stopped.stopped = true;
  stopped.diagnostics_sent = 31;
  dds::BatchArrivals partial = got;
  partial.lines_rejected = 1;
  partial.lines_deleted = 29;
  EXPECT_EQ(dds::check_counts(stopped, partial), "");
  partial.lines_deleted = 41;
  partial.lines_rejected = 0;
  EXPECT_NE(dds::check_counts(stopped, partial).find("block-delete"), std::string::npos);
}

// Batch mode hands a line's diagnostic to the writer before the blocks of that line (a rejected
// cycle: "G275 rejected", then its skip moves); the merge must do the same, keep equal-line
// blocks in order, and never reorder across lines.
TEST(DdsConvert, MergeByLinePutsTheDiagnosticBeforeTheBlocksOfItsLine) {
  msg::BlockBatch batch;
  for (std::uint64_t line : {2, 5, 5, 5, 7, 9}) {
    msg::Block& b = batch.blocks().emplace_back();
    b.line(line);
    b.text(std::to_string(batch.blocks().size() - 1));
  }
  for (std::uint64_t line : {1, 5, 8, 10}) batch.diagnostics().emplace_back().line(line);
  std::string order;
  dds::for_each_in_line_order(
      batch,
      [&](std::size_t b) {
        order += "b" + std::to_string(batch.blocks()[b].line()) + "." + batch.blocks()[b].text() + " ";
        return true;
      },
      [&](std::size_t d) {
        order += "d" + std::to_string(batch.diagnostics()[d].line()) + " ";
        return true;
      });
  EXPECT_EQ(order, "d1 b2.0 d5 b5.1 b5.2 b5.3 b7.4 d8 b9.5 d10 ");
  // A callback returning false stops the walk (a corrupt sample ends the program).
  int calls = 0;
  dds::for_each_in_line_order(
      batch, [&](std::size_t) { return ++calls < 3; }, [&](std::size_t) { return ++calls < 3; });
  EXPECT_EQ(calls, 3);
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
  bad.path_mode(3);
  EXPECT_FALSE(dds::from_msg(bad, b, &why));
  EXPECT_NE(why.find("'path_mode'"), std::string::npos) << why;
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
  dds::to_msg(Diagnostic{"f", 1, 2, Severity::kError, "m"}, dds::DiagnosticKind::kLineRejected, d);
  Diagnostic out;
  dds::DiagnosticKind st{};
  for (std::uint8_t invalid : {0, 4}) {  // 0 = LineStatus::kBlock: a block has no diagnostic
    d.line_status(invalid);
    EXPECT_FALSE(dds::from_msg(d, out, st, &why));
    EXPECT_NE(why.find("line_status"), std::string::npos);
  }
  d.line_status(static_cast<std::uint8_t>(dds::DiagnosticKind::kBlockRejected));
  EXPECT_TRUE(dds::from_msg(d, out, st, &why)) << why;
  EXPECT_EQ(st, dds::DiagnosticKind::kBlockRejected);
  d.severity(3);
  EXPECT_FALSE(dds::from_msg(d, out, st, &why));
  EXPECT_NE(why.find("severity"), std::string::npos);
}

// One edge has one writer: batches of one program from a second writer (the stage before runs
// twice on the domain, e.g. two pipelines on one domain id) make the program's error say so,
// before the sequence error the mix also causes; the first writer's batches alone are fine.
TEST(DdsConvert, ASecondWriterOfOneProgramIsNamedAsSuch) {
  dds::BatchIntake<dds::BatchProgram> intake("write", "gcpipe_toolpath");
  auto batch = [](std::uint64_t sequence) {
    msg::BlockBatch b;
    b.program_id(7);
    b.file("part.nc");
    b.sequence_number(sequence);
    return b;
  };
  auto make = [] { return dds::BatchProgram{}; };
  dds::BatchProgram* p = intake.admit(batch(0), false, 11, make);
  ASSERT_NE(p, nullptr);
  ASSERT_EQ(intake.admit(batch(1), false, 11, make), p);
  EXPECT_EQ(p->error, "");
  ASSERT_EQ(intake.admit(batch(0), false, 22, make), p);
  EXPECT_EQ(p->error.rfind("a second writer on gcpipe_toolpath sends this program too", 0), 0u) << p->error;
  EXPECT_NE(p->error.find("give each pipeline its own domain"), std::string::npos) << p->error;
}

}  // namespace
}  // namespace gcpipe
