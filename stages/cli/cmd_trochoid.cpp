// gcpipe trochoid: parse -> trochoid -> write.
#include <unistd.h>

#include <filesystem>
#include <iostream>

#include <nlohmann/json.hpp>

#include "commands.hpp"
#include "program_run.hpp"

namespace gcpipe::cli {

int run_trochoid(const TrochoidArgs& a) {
  pipeline::install_stop_handlers();
  PrintedLog log;
  ProgramRun run(a, {"write"}, log);
  TextFileSink out(a.output);
  run.pipeline().attach("write", out);
  const bool complete = run.run();
  if (pipeline::stop_requested()) return exit_status(complete, "", 0);
  out.commit();
  // The report step draws the engagement figure; --png names where it goes.
  nlohmann::ordered_json report;
  std::string text;
  std::vector<std::string> files;
  const std::filesystem::path png_dir = a.png.empty() ? std::filesystem::path() : std::filesystem::temp_directory_path() / ("gcpipe_trochoid_" + std::to_string(::getpid()));
  if (!png_dir.empty()) std::filesystem::create_directories(png_dir / "plots");
  run.pipeline().report(report, text, png_dir, std::filesystem::path(run.input_name()).filename().string(), files, {});
  const auto& t = report["trochoid"];
  std::fprintf(stderr, "%s: %llu G275 cycles expanded, %llu rejected, %llu blocks written\n", run.input_name().c_str(),
               t["cycles_expanded"].get<unsigned long long>(), t["cycles_rejected"].get<unsigned long long>(),
               report["blocks_written"].get<unsigned long long>());
  if (!png_dir.empty()) {
    if (files.empty()) {
      std::cerr << "gcpipe trochoid: no G275 cycle expanded, no figure written to " << a.png << "\n";
    } else {
      std::filesystem::copy_file(png_dir / files.front(), a.png, std::filesystem::copy_options::overwrite_existing);
      std::fprintf(stderr, "%s: max radial engagement %.2f deg (ae %.3f mm); figure %s\n", run.input_name().c_str(),
                   t["max_engagement_deg"].get<double>(), t["max_ae_mm"].get<double>(), a.png.c_str());
    }
    std::filesystem::remove_all(png_dir);
  }
  if (!complete) std::cerr << "gcpipe trochoid: " << run.error() << "\n";
  return exit_status(complete, "", run.pipeline().rejected());
}

}  // namespace gcpipe::cli
