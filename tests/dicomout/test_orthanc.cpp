// The PACS round trip (docs/pacs.md): a real Orthanc on loopback with a test
// user, the sample CT sent with storescu, `mandisym orthanc` following the
// change log, and the SEG, SR and report fetched back over REST and checked
// against the run's own files. Every process is stopped by its PID.
#include <gtest/gtest.h>

#include <arpa/inet.h>
#include <fcntl.h>
#include <netinet/in.h>
#include <signal.h>
#include <spawn.h>
#include <sys/socket.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <map>
#include <thread>

#include <dcmtk/config/osconfig.h>
#include <dcmtk/dcmdata/dctk.h>

#include "core/files.h"
#include "core/json_text.h"
#include "io/volume_io.h"
#include "pipeline/orthanc_client.h"
#include "tests/support/dicom_readback.h"

namespace fs = std::filesystem;

namespace {

const fs::path kSample = fs::path(MANDISYM_SOURCE_DIR) / "sample_dicom" / "symmetric" / "dicom";

bool have(const std::string& tool) { return std::system(("command -v " + tool + " > /dev/null 2>&1").c_str()) == 0; }

int free_port() {
  const int fd = ::socket(AF_INET, SOCK_STREAM, 0);
  sockaddr_in a{};
  a.sin_family = AF_INET;
  a.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  ::bind(fd, reinterpret_cast<sockaddr*>(&a), sizeof a);
  socklen_t n = sizeof a;
  ::getsockname(fd, reinterpret_cast<sockaddr*>(&a), &n);
  ::close(fd);
  return ntohs(a.sin_port);
}

// A background process with its output in a log file and TCP_NODELAY=1 set
// (DCMTK and Orthanc otherwise leave Nagle's algorithm on).
pid_t spawn(const std::vector<std::string>& args, const fs::path& log) {
  std::vector<char*> argv;
  std::vector<std::string> a = args;
  for (auto& x : a) argv.push_back(x.data());
  argv.push_back(nullptr);
  std::vector<std::string> env_s = {"TCP_NODELAY=1"};
  for (char** e = environ; *e; ++e) env_s.emplace_back(*e);
  std::vector<char*> envp;
  for (auto& x : env_s) envp.push_back(x.data());
  envp.push_back(nullptr);
  posix_spawn_file_actions_t fa;
  posix_spawn_file_actions_init(&fa);
  posix_spawn_file_actions_addopen(&fa, 1, log.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0600);
  posix_spawn_file_actions_adddup2(&fa, 1, 2);
  pid_t pid = -1;
  posix_spawnp(&pid, a[0].c_str(), &fa, nullptr, argv.data(), envp.data());
  posix_spawn_file_actions_destroy(&fa);
  return pid;
}

// SIGTERM, then SIGKILL after 20 s; true when it exited on SIGTERM.
bool stop(pid_t pid) {
  if (pid <= 0) return true;
  ::kill(pid, SIGTERM);
  for (int k = 0; k < 200; ++k) {
    if (::waitpid(pid, nullptr, WNOHANG) == pid) return true;
    std::this_thread::sleep_for(std::chrono::milliseconds(100));
  }
  ::kill(pid, SIGKILL);
  ::waitpid(pid, nullptr, 0);
  return false;
}

struct Orthanc {
  fs::path dir;
  int http = 0, dicom = 0;
  pid_t pid = -1;
  std::string url() const { return "http://127.0.0.1:" + std::to_string(http); }
};

Orthanc start_orthanc(const fs::path& dir) {
  Orthanc o{dir, free_port(), free_port()};
  ms::Json c;
  c["Name"] = "MandiSymTest";
  c["StorageDirectory"] = (dir / "db").string();
  c["IndexDirectory"] = (dir / "db").string();
  c["HttpPort"] = o.http;
  c["DicomPort"] = o.dicom;
  c["DicomAet"] = "ORTHANC";
  c["RemoteAccessAllowed"] = false;
  c["AuthenticationEnabled"] = true;
  c["RegisteredUsers"] = {{"mandisym", "test-secret"}};
  c["StableAge"] = 2;
  c["UserMetadata"] = {{"MandiSym", 1024}};
  c["Plugins"] = ms::Json::array();
  std::ofstream(dir / "orthanc.json") << ms::dump_json(c, 2);
  std::ofstream(dir / "credentials") << "mandisym:test-secret\n";
  o.pid = spawn({"Orthanc", (dir / "orthanc.json").string()}, dir / "orthanc.log");
  return o;
}

// Orthanc started and answering with the test user (a test failure otherwise).
bool wait_until_up(const ms::pipeline::OrthancClient& pacs) {
  for (int k = 0; k < 100; ++k) {
    try {
      if (pacs.get_json("/system").contains("Version")) return true;
    } catch (const std::exception&) {
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(100));
  }
  return false;
}

pid_t start_node(const Orthanc& o) {
  return spawn({MANDISYM_BINARY, "orthanc", "--url", o.url(), "--credentials", (o.dir / "credentials").string(), "--work",
                (o.dir / "work").string(), "--poll", "0.5"},
               o.dir / "node.log");
}

fs::path fresh_dir(const std::string& name) {
  const fs::path dir = fs::temp_directory_path() / ("mandisym_orthanc_" + name + "_" + std::to_string(::getpid()));
  fs::remove_all(dir);
  fs::create_directories(dir);
  return dir;
}

// The study's series by modality, once SEG, SR and DOC are all there (or the deadline passed).
std::map<std::string, std::string> wait_for_outputs(const ms::pipeline::OrthancClient& pacs, double deadline_s) {
  const auto t0 = std::chrono::steady_clock::now();
  std::map<std::string, std::string> by_modality;
  while (std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count() < deadline_s) {
    by_modality.clear();
    for (const ms::Json& id : pacs.get_json("/series")) {
      const ms::Json s = pacs.get_json("/series/" + id.get<std::string>());
      by_modality[s["MainDicomTags"].value("Modality", "")] = s["Instances"].at(0).get<std::string>();
    }
    if (by_modality.count("SEG") && by_modality.count("SR") && by_modality.count("DOC")) break;
    std::this_thread::sleep_for(std::chrono::milliseconds(250));
  }
  return by_modality;
}

std::string tool_output(const std::string& cmd, int* rc) {
  const fs::path out = fs::temp_directory_path() / ("mandisym_tool_" + std::to_string(::getpid()) + ".txt");
  *rc = std::system((cmd + " > " + out.string() + " 2>&1").c_str());
  const std::string text = ms::read_file_or_empty(out.string());
  fs::remove(out);
  return text;
}

}  // namespace

TEST(OrthancRoundTrip, StoredCtComesBackWithSegSrAndReportInItsStudy) {
  if (!have("Orthanc") || !have("storescu")) GTEST_SKIP() << "Orthanc or storescu not installed (scripts/install-deps)";
  const fs::path dir = fresh_dir("roundtrip");
  Orthanc orthanc = start_orthanc(dir);
  const ms::pipeline::OrthancClient pacs(orthanc.url(), "mandisym:test-secret");
  ASSERT_TRUE(wait_until_up(pacs)) << ms::read_file_or_empty((dir / "orthanc.log").string());
  // The node is started first, as a hospital would run it, then the CT arrives.
  const pid_t node = start_node(orthanc);
  const auto t0 = std::chrono::steady_clock::now();
  int rc = 0;
  const std::string sent = tool_output("TCP_NODELAY=1 storescu -xs -aec ORTHANC 127.0.0.1 " + std::to_string(orthanc.dicom) + " +sd " +
                                           kSample.string(), &rc);
  EXPECT_EQ(rc, 0) << sent;
  const auto outputs = wait_for_outputs(pacs, 180);
  const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  std::cout << "storescu to SEG, SR and report stored back: " << seconds << " s\n";
  RecordProperty("round_trip_seconds", std::to_string(seconds));
  // The outputs become stable series in turn (StableAge 2 s); the node must leave them alone.
  const auto skipped_all = [&] {
    const std::string log = ms::read_file_or_empty((dir / "work" / "orthanc.log").string());
    for (const char* m : {"SEG", "SR", "DOC"})
      if (log.find(std::string("skipped (modality ") + m + ")") == std::string::npos) return false;
    return true;
  };
  for (int k = 0; k < 300 && !skipped_all(); ++k) std::this_thread::sleep_for(std::chrono::milliseconds(100));
  const bool node_stopped = stop(node);
  ASSERT_TRUE(outputs.count("SEG") && outputs.count("SR") && outputs.count("DOC")) << ms::read_file_or_empty((dir / "node.log").string());

  // All four series are in one study.
  EXPECT_EQ(pacs.get_json("/studies").size(), 1u);
  // The run's own files, for comparison.
  fs::path results;
  for (const auto& e : fs::directory_iterator(dir / "work" / "results")) results = e.path();
  std::map<std::string, fs::path> fetched;
  for (const auto& [modality, instance] : outputs) {
    fetched[modality] = dir / (modality + ".dcm");
    pacs.download("/instances/" + instance + "/file", fetched[modality].string());
  }
  EXPECT_EQ(tool_output("dcmdump " + fetched["SEG"].string(), &rc).find("SegmentSequence") != std::string::npos, true);
  EXPECT_EQ(rc, 0);
  EXPECT_NE(tool_output("dsrdump " + fetched["SR"].string(), &rc).find("Imaging Measurement Report"), std::string::npos);
  EXPECT_EQ(rc, 0);
  if (have("dciodvfy"))
    for (const char* m : {"SEG", "SR", "DOC"}) {
      const std::string report = tool_output("dciodvfy " + fetched[m].string(), &rc);
      EXPECT_EQ(report.find("Error"), std::string::npos) << m << ":\n" << report;
    }
  // SEG frames = the run's mask, voxel for voxel in world coordinates.
  const ms::Mask mask = ms::io::read_mask((results / "mandible_mask.nii.gz").string());
  const ms::test::SegComparison c = ms::test::compare_seg_with_mask(fetched["SEG"].string(), mask);
  EXPECT_EQ(c.mismatches, 0u);
  EXPECT_EQ(c.set_pixels, mask.count());
  // The report object holds the run's report.pdf byte for byte.
  DcmFileFormat pdf;
  ASSERT_TRUE(pdf.loadFile(fetched["DOC"].c_str()).good());
  const Uint8* bytes = nullptr;
  unsigned long n = 0;
  pdf.getDataset()->findAndGetUint8Array(DCM_EncapsulatedDocument, bytes, &n);
  const std::string expected = ms::read_file_or_empty((results / "report.pdf").string());
  ASSERT_GE(n, expected.size());
  EXPECT_EQ(std::string(reinterpret_cast<const char*>(bytes), expected.size()), expected);
  // SR numbers = results.json.
  EXPECT_EQ(ms::test::sr_numbers_mismatching_results(fetched["SR"].string(), (results / "results.json").string()), "");
  // The CT series carries the node's record.
  bool found = false;
  std::string ct;
  for (const ms::Json& id : pacs.get_json("/series"))
    if (pacs.get_json("/series/" + id.get<std::string>())["MainDicomTags"].value("Modality", "") == "CT") ct = id.get<std::string>();
  EXPECT_EQ(pacs.get_text("/series/" + ct + "/metadata/MandiSym", &found).rfind("ok instances=", 0), 0u);
  // Its own outputs were seen and left alone.
  const std::string node_log = ms::read_file_or_empty((dir / "work" / "orthanc.log").string());
  for (const char* m : {"SEG", "SR", "DOC"})
    EXPECT_NE(node_log.find(std::string("skipped (modality ") + m + ")"), std::string::npos) << node_log;
  EXPECT_EQ(node_log.find("failed instances"), std::string::npos) << node_log;

  EXPECT_TRUE(node_stopped) << "mandisym orthanc did not stop on SIGTERM";
  EXPECT_TRUE(stop(orthanc.pid)) << "Orthanc did not stop on SIGTERM";
  EXPECT_NE(::kill(node, 0), 0);
  EXPECT_NE(::kill(orthanc.pid, 0), 0);
  fs::remove_all(dir);
}

TEST(OrthancRoundTrip, FailedSeriesGetsARecordAndLosesNothing) {
  if (!have("Orthanc") || !have("storescu") || !have("dcmodify")) GTEST_SKIP() << "Orthanc or DCMTK tools not installed";
  const fs::path dir = fresh_dir("failed");
  // Three slices of the sample as a series of their own: too few for a head CT (exit 4).
  fs::create_directories(dir / "short");
  int k = 0;
  for (const auto& e : fs::directory_iterator(kSample))
    if (k++ < 3) fs::copy_file(e.path(), dir / "short" / e.path().filename());
  int rc = 0;
  const std::string modified = tool_output("dcmodify -nb -gin -m '(0020,000d)=1.2.826.0.1.3680043.8.498.1' -m '(0020,000e)=1.2.826.0.1.3680043.8.498.2' " +
                                               (dir / "short").string() + "/*", &rc);
  ASSERT_EQ(rc, 0) << modified;
  Orthanc orthanc = start_orthanc(dir);
  const ms::pipeline::OrthancClient pacs(orthanc.url(), "mandisym:test-secret");
  ASSERT_TRUE(wait_until_up(pacs)) << ms::read_file_or_empty((dir / "orthanc.log").string());
  const pid_t node = start_node(orthanc);
  const std::string sent = tool_output("TCP_NODELAY=1 storescu -xs -aec ORTHANC 127.0.0.1 " + std::to_string(orthanc.dicom) + " +sd " +
                                           (dir / "short").string(), &rc);
  EXPECT_EQ(rc, 0) << sent;
  std::string record, series;
  bool found = false;
  for (int t = 0; t < 600 && !found; ++t) {
    std::this_thread::sleep_for(std::chrono::milliseconds(100));
    const ms::Json all = pacs.get_json("/series");
    if (all.empty()) continue;
    series = all.at(0).get<std::string>();
    record = pacs.get_text("/series/" + series + "/metadata/MandiSym", &found);
  }
  EXPECT_TRUE(stop(node));
  EXPECT_EQ(record.rfind("failed instances=3 exit=4 ", 0), 0u) << record;
  EXPECT_NE(record.find("too few"), std::string::npos) << record;
  // Nothing stored back, nothing lost.
  EXPECT_EQ(pacs.get_json("/series").size(), 1u);
  EXPECT_EQ(pacs.get_json("/series/" + series + "/instances").size(), 3u);
  EXPECT_NE(ms::read_file_or_empty((dir / "work" / "orthanc.log").string()).find("failed instances=3"), std::string::npos);
  EXPECT_TRUE(stop(orthanc.pid));
  fs::remove_all(dir);
}

// Bad invocations: one line on stderr and a documented exit code, before anything is written.
TEST(OrthancNode, BadInvocationsAreRefusedWithTheirExitCode) {
  const fs::path dir = fresh_dir("bad");
  std::ofstream(dir / "nocolon") << "justauser\n";
  const std::string bin = MANDISYM_BINARY, work = " --work " + (dir / "w").string();
  const std::vector<std::pair<std::string, int>> cases = {
      {" orthanc" + work, 2},                                                                  // no --url
      {" orthanc --url ftp://127.0.0.1:1" + work, 2},                                          // not http(s)
      {" orthanc --url http://127.0.0.1:1", 2},                                                // no --work
      {" orthanc --url http://127.0.0.1:1 --credentials " + (dir / "nocolon").string() + work, 2},
      {" orthanc --url http://127.0.0.1:1" + work + " -- --bogus-option", 2},                 // run options checked first
      {" orthanc --url http://127.0.0.1:1" + work + " --once", 3},                             // nobody listening
  };
  for (const auto& [args, code] : cases) {
    int rc = 0;
    const std::string err = tool_output(bin + args, &rc);
    EXPECT_TRUE(WIFEXITED(rc) && WEXITSTATUS(rc) == code) << args << " -> " << rc << ": " << err;
    EXPECT_EQ(std::count(err.begin(), err.end(), '\n'), 1) << args << ": " << err;
    EXPECT_NE(err.find("mandisym: error: "), std::string::npos) << args << ": " << err;
  }
  EXPECT_FALSE(fs::exists(dir / "w" / "state.json"));
  fs::remove_all(dir);
}
