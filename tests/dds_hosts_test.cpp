// The pipeline across hosts (issue 11, items 5 and 6): two network namespaces joined by a veth
// pair stand for two machines of a shop network. Every process runs inside one of them, with the
// shipped shop profile (pipeline_configs/dds_network_shop.xml: UDP on the listed addresses only,
// unicast discovery, no shared memory) rewritten to the test's own two addresses. Nothing can leave
// the namespaces: they hold a loopback and their end of the veth pair, nothing else.
//
// Needs root (CAP_SYS_ADMIN, CAP_NET_ADMIN) for `ip netns add`; skipped with a message otherwise.
#include <gtest/gtest.h>

#include "dds_test_util.hpp"

#include <unistd.h>

#include <cstdlib>
#include <fstream>
#include <string>
#include <vector>

namespace {

namespace fs = std::filesystem;
using gcpipe_test::Process;
using gcpipe_test::slurp;
using gcpipe_test::wait_for_log;

const fs::path kSource = GCPIPE_SOURCE_DIR;
const std::string kConfig = (kSource / "pipeline_configs" / "default.yaml").string();
// The namespaces have their own ports and no shared memory is used: any domain id will do.
constexpr const char* kDomain = "17";
constexpr const char* kHostA = "10.231.0.1";
constexpr const char* kHostB = "10.231.0.2";

bool run(const std::string& command) { return std::system((command + " > /dev/null 2>&1").c_str()) == 0; }

// Replaces every `from` in `text` by `to`; the number of replacements.
int replace_all(std::string& text, const std::string& from, const std::string& to) {
  int n = 0;
  for (std::size_t at = text.find(from); at != std::string::npos; at = text.find(from, at + to.size()), ++n)
    text.replace(at, from.size(), to);
  return n;
}

class TwoHosts : public ::testing::Test {
 protected:
  void SetUp() override {
    const std::string id = std::to_string(getpid());
    ns_a_ = "gcpipeA" + id;
    ns_b_ = "gcpipeB" + id;
    veth_a_ = "gcv" + id + "a";
    veth_b_ = "gcv" + id + "b";
    if (!run("ip netns add " + ns_a_)) GTEST_SKIP() << "cannot create a network namespace here (`ip netns add` needs root): the across-hosts test did not run";
    created_ = true;
    ASSERT_TRUE(run("ip netns add " + ns_b_));
    ASSERT_TRUE(run("ip link add " + veth_a_ + " type veth peer name " + veth_b_));
    ASSERT_TRUE(run("ip link set " + veth_a_ + " netns " + ns_a_));
    ASSERT_TRUE(run("ip link set " + veth_b_ + " netns " + ns_b_));
    ASSERT_TRUE(run("ip -n " + ns_a_ + " addr add " + kHostA + "/24 dev " + veth_a_));
    ASSERT_TRUE(run("ip -n " + ns_b_ + " addr add " + kHostB + "/24 dev " + veth_b_));
    for (const auto& [ns, dev] : {std::pair{ns_a_, veth_a_}, std::pair{ns_b_, veth_b_}}) {
      ASSERT_TRUE(run("ip -n " + ns + " link set " + dev + " up"));
      ASSERT_TRUE(run("ip -n " + ns + " link set lo up"));
    }
    const auto* info = ::testing::UnitTest::GetInstance()->current_test_info();
    dir_ = fs::temp_directory_path() / ("gcpipe_hosts_" + std::string(info->name()) + "_" + id);
    fs::remove_all(dir_);
    fs::create_directories(dir_);
    network_ = write_network_profile();
  }

  void TearDown() override {
    if (!created_) return;
    run("ip netns del " + ns_a_);  // takes its end of the veth pair, and so the pair, with it
    run("ip netns del " + ns_b_);
    if (!HasFailure()) fs::remove_all(dir_);
    else std::cerr << "logs kept in " << dir_ << "\n";
  }

  // The shipped shop profile with its two example hosts replaced by the namespaces' addresses:
  // each appears twice (interface allow-list and initial peers).
  fs::path write_network_profile() {
    std::string xml = slurp(kSource / "pipeline_configs" / "dds_network_shop.xml");
    EXPECT_EQ(replace_all(xml, "192.0.2.11", kHostA), 2);
    EXPECT_EQ(replace_all(xml, "192.0.2.12", kHostB), 2);
    const fs::path f = dir_ / "network.xml";
    std::ofstream(f) << xml;
    return f;
  }

  std::vector<std::string> on(const std::string& ns) const { return {"ip", "netns", "exec", ns}; }

  // gcpipe ARGS on the shop network, with `identity` when not empty.
  std::vector<std::string> net(std::vector<std::string> args, const std::string& identity = "",
                               const char* timeout = "60") const {
    const std::vector<std::string> common = {"--network", network_.string(), "--domain", kDomain,
                                             "--idle-timeout", "60", "--timeout", timeout};
    args.insert(args.end(), common.begin(), common.end());
    if (!identity.empty()) args.insert(args.end(), {"--identity", identity});
    return args;
  }

  // Bytes sent out of host A's end of the pair so far.
  long long bytes_sent_by_a() const {
    const fs::path f = dir_ / "tx_bytes";
    const std::string read = "ip netns exec " + ns_a_ + " cat /sys/class/net/" + veth_a_ + "/statistics/tx_bytes > " + f.string();
    EXPECT_EQ(std::system(read.c_str()), 0) << read;
    return std::atoll(slurp(f).c_str());
  }

  std::string batch_file(const fs::path& input, const std::string& name) {
    Process batch("batch", {"batch", input.string(), "-o", (dir_ / "batch").string(), "--config", kConfig, "--quiet"}, dir_);
    EXPECT_EQ(batch.wait(), 0) << slurp(batch.log);
    return slurp(dir_ / "batch" / name);
  }

  std::string ns_a_, ns_b_, veth_a_, veth_b_;
  bool created_ = false;
  fs::path dir_, network_;
};

// The whole chain split over two hosts: feed, parse, trochoid, force and ik on A; write,
// simulate, compensate and both sinks on B. output.nc and compensated.nc are batch's bytes, and
// the program went over the wire.
TEST_F(TwoHosts, WholeChainSplitOverTwoHostsWritesBatchsBytes) {
  const fs::path input = kSource / "samples" / "five_axis_demo.nc";
  const std::string expected_output = batch_file(input, "output.nc");
  const std::string expected_compensated = slurp(dir_ / "batch" / "compensated.nc");
  ASSERT_FALSE(expected_compensated.empty());
  const long long sent_before = bytes_sent_by_a();
  const fs::path out = dir_ / "output.nc", comp = dir_ / "compensated.nc";
  const auto a = on(ns_a_), b = on(ns_b_);
  Process sink("sink", net({"sink", "-o", out.string()}), dir_, b);
  Process sink_comp("sink_comp", net({"sink", "--in", "gcpipe_compensated", "-o", comp.string()}), dir_, b);
  ASSERT_TRUE(wait_for_log(sink, "gcpipe sink: ready")) << slurp(sink.log);
  ASSERT_TRUE(wait_for_log(sink_comp, "gcpipe sink: ready")) << slurp(sink_comp.log);
  Process compensate("compensate", net({"node", "compensate", "--config", kConfig}), dir_, b);
  Process simulate("simulate", net({"node", "simulate", "--config", kConfig}), dir_, b);
  Process write("write", net({"node", "write", "--config", kConfig}), dir_, b);
  Process ik("ik", net({"node", "ik", "--config", kConfig}), dir_, a);
  Process force("force", net({"node", "force", "--config", kConfig}), dir_, a);
  Process trochoid("trochoid", net({"node", "trochoid", "--config", kConfig, "--subscribers", "2"}), dir_, a);
  Process parse("parse", net({"node", "parse", "--config", kConfig}), dir_, a);
  Process feed("feed", net({"feed", input.string(), "--config", kConfig}), dir_, a);
  EXPECT_EQ(feed.wait(), 0) << slurp(feed.log);
  for (Process* p : {&sink, &sink_comp, &compensate, &simulate, &write, &ik, &force, &trochoid, &parse})
    EXPECT_EQ(p->wait(), 0) << p->name << ": " << slurp(p->log);
  EXPECT_TRUE(slurp(out) == expected_output) << "output.nc differs from batch's";
  EXPECT_TRUE(slurp(comp) == expected_compensated) << "compensated.nc differs from batch's";
  // A sends B at least the program's blocks (write's and simulate's inputs) and the IK telemetry.
  EXPECT_GT(bytes_sent_by_a() - sent_before, static_cast<long long>(expected_output.size()));
}

// DDS Security on the shop network (issue 11, item 6): identities made by make_security.sh. A
// participant without an identity and one with the monitor's (no publish permission) both fail
// to put a program into the pipeline; the feeder's goes through and the output is batch's. The
// monitor identity reads the monitor copies; a participant without an identity reads nothing.
TEST_F(TwoHosts, SecuredPipelineTakesProgramsOnlyFromItsFeeder) {
  const fs::path ids = dir_ / "security";
  ASSERT_TRUE(run("bash " + (kSource / "stages" / "dds" / "make_security.sh").string() + " " + ids.string() + " " + kDomain));
  const std::string node = (ids / "node").string(), feeder = (ids / "feeder").string(), monitor = (ids / "monitor").string();
  const fs::path input = kSource / "samples" / "trochoid_slot_seed000.nc";
  Process batch("batch", {"batch", input.string(), "-o", (dir_ / "batch").string(), "--config", kConfig, "--quiet", "--no-simulate"}, dir_);
  ASSERT_EQ(batch.wait(), 0) << slurp(batch.log);
  const std::string expected = slurp(dir_ / "batch" / "output.nc");
  const fs::path out = dir_ / "output.nc";
  const auto a = on(ns_a_), b = on(ns_b_);
  Process sink("sink", net({"sink", "-o", out.string()}, node), dir_, b);
  ASSERT_TRUE(wait_for_log(sink, "gcpipe sink: ready")) << slurp(sink.log);
  Process write("write", net({"node", "write", "--config", kConfig}, node), dir_, b);
  Process watcher("monitor", net({"monitor", "gcpipe_gcode", "--period", "5"}, monitor), dir_, b);
  Process eavesdropper("eavesdropper", net({"monitor", "gcpipe_gcode", "--period", "5"}), dir_, b);
  Process trochoid("trochoid", net({"node", "trochoid", "--config", kConfig}, node), dir_, a);
  Process parse("parse", net({"node", "parse", "--config", kConfig}, node), dir_, a);

  Process stranger("feed_unauthenticated", net({"feed", input.string(), "--config", kConfig}, "", "5"), dir_, a);
  EXPECT_NE(stranger.wait(), 0);
  EXPECT_NE(slurp(stranger.log).find("no reader of gcpipe_program"), std::string::npos) << slurp(stranger.log);
  Process watcher_feeds("feed_as_monitor", net({"feed", input.string(), "--config", kConfig}, monitor, "5"), dir_, a);
  EXPECT_NE(watcher_feeds.wait(), 0);
  EXPECT_NE(slurp(watcher_feeds.log).find("do not allow it to publish"), std::string::npos) << slurp(watcher_feeds.log);

  Process feed("feed", net({"feed", input.string(), "--config", kConfig}, feeder), dir_, a);
  EXPECT_EQ(feed.wait(), 0) << slurp(feed.log);
  for (Process* p : {&sink, &write, &trochoid, &parse}) EXPECT_EQ(p->wait(), 0) << p->name << ": " << slurp(p->log);
  EXPECT_TRUE(slurp(out) == expected) << "the secured pipeline's output differs from batch's";
  EXPECT_EQ(watcher.wait(), 0) << slurp(watcher.log);
  EXPECT_NE(slurp(watcher.log).find("end of program:"), std::string::npos) << slurp(watcher.log);
  // The monitor without an identity is still waiting for a writer it will never be matched with.
  kill(eavesdropper.pid, SIGTERM);
  eavesdropper.wait(10);
  const std::string heard = slurp(eavesdropper.log);
  EXPECT_EQ(heard.find("matched"), std::string::npos) << heard;
  EXPECT_EQ(heard.find("end of program"), std::string::npos) << heard;
}

}  // namespace
