// pipeline::AtomicFile: a file appears under its final name only when complete, an abandoned one
// leaves nothing, and a device (-o /dev/null) is written in place, never replaced.
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <unistd.h>

#include "output_dir.hpp"

namespace fs = std::filesystem;
using gcpipe::pipeline::AtomicFile;

namespace {

fs::path scratch(const std::string& name) {
  const fs::path d = fs::temp_directory_path() / ("gcpipe_output_dir_" + name + "_" + std::to_string(getpid()));
  fs::remove_all(d);
  fs::create_directories(d);
  return d;
}

TEST(AtomicFile, AppearsUnderItsNameOnlyWhenCommitted) {
  const fs::path d = scratch("commit"), f = d / "out.txt";
  {
    AtomicFile a(f.string());
    std::string text = "line\n";
    a.write(text, true);
    EXPECT_FALSE(fs::exists(f));
    EXPECT_TRUE(fs::exists(d / "out.txt.part"));
    a.commit();
  }
  EXPECT_TRUE(fs::exists(f));
  EXPECT_FALSE(fs::exists(d / "out.txt.part"));
  fs::remove_all(d);
}

TEST(AtomicFile, AnAbandonedFileLeavesNothing) {
  const fs::path d = scratch("abandon");
  {
    AtomicFile a((d / "out.txt").string());
    std::string text = "half";
    a.write(text, true);
  }
  EXPECT_TRUE(fs::is_empty(d));
  fs::remove_all(d);
}

TEST(AtomicFile, ADeviceIsWrittenInPlaceNotReplaced) {
  ASSERT_TRUE(fs::is_character_file("/dev/null")) << "/dev/null is not a device before the test";
  {
    AtomicFile a("/dev/null");
    std::string text(2 << 20, 'x');
    a.write(text);
    a.commit();
  }
  EXPECT_TRUE(fs::is_character_file("/dev/null")) << "AtomicFile replaced /dev/null with a regular file";
  EXPECT_FALSE(fs::exists("/dev/null.part"));
}

}  // namespace
