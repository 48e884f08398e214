// SPDX-License-Identifier: GPL-3.0-or-later
// A seeded mutation fuzzer over the loaders a user's files reach: the Mitsuba XML scene loader
// (parse and build, which loads the meshes it names), the OBJ reader and the PLY reader (ASCII
// and binary). Each mutant of the corpus in tests/core/fuzz_corpus is written to a temporary
// file and loaded; the loader must either succeed or throw InputError whose message starts with
// `file:line` (the user must be told where). Any other exception fails the test, a crash kills
// it (and ASan/UBSan, which run the unit label in CI, turn memory errors into crashes), and a
// watchdog aborts an input that runs longer than kHangSeconds, and the process's peak memory must
// stay below kPeakMemoryBytes (a 4 GB allocation from a 20-byte file is a bug too). A failing
// input is kept beside the temporary directory and its mutation index printed; after a crash the
// input is the directory's fuzz.<ext>.
#include <gtest/gtest.h>
#include <sys/resource.h>
#include <unistd.h>

#include <atomic>
#include <chrono>
#include <condition_variable>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <iterator>
#include <mutex>
#include <regex>
#include <string>
#include <thread>
#include <typeinfo>
#include <vector>

#include "core/geometry/mesh_io.h"
#include "core/scene/scene.h"
#include "core/scene/scene_desc.h"

namespace gdmlt {
namespace {

namespace fs = std::filesystem;

/// An input that takes this long is a hang. A clean input loads in about a millisecond in the
/// release build; ASan/UBSan are 2-20x slower, so a legitimate input stays far below.
constexpr double kHangSeconds = 20.0;
/// Loading these small files needs a few MB; ASan's shadow memory and quarantine add a few
/// hundred. The PLY list bug this found took 4 GB.
constexpr double kPeakMemoryBytes = 2.0 * 1024 * 1024 * 1024;

/// splitmix64 (Steele et al. 2014): its own generator so that the sequence of mutants is the
/// same with every standard library (std:: distributions are implementation-defined).
class FuzzRandom {
  public:
    explicit FuzzRandom(std::uint64_t seed) : state_(seed) {}
    std::uint64_t next() {
        std::uint64_t z = (state_ += 0x9e3779b97f4a7c15ull);
        z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ull;
        z = (z ^ (z >> 27)) * 0x94d049bb133111ebull;
        return z ^ (z >> 31);
    }
    /// Uniform in [0, n) (n > 0; the modulo bias is irrelevant here).
    std::size_t below(std::size_t n) { return static_cast<std::size_t>(next() % n); }

  private:
    std::uint64_t state_;
};

std::string read_bytes(const fs::path& path) {
    std::ifstream in(path, std::ios::binary);
    if (!in) throw std::runtime_error("cannot read fuzz corpus file " + path.string());
    return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}

void write_bytes(const fs::path& path, const std::string& bytes) {
    std::ofstream out(path, std::ios::binary | std::ios::trunc);
    out.write(bytes.data(), static_cast<std::streamsize>(bytes.size()));
    if (!out) throw std::runtime_error("cannot write fuzz input " + path.string());
}

/// Numbers that have broken parsers: overflow of float, int32, uint32 and int64, NaN and
/// infinities in every spelling, negative zero, denormals, hex, and nothing at all.
const std::vector<std::string>& interesting_numbers() {
    static const std::vector<std::string> numbers = {"1e308",
                                                     "-1e308",
                                                     "1e309",
                                                     "nan",
                                                     "-nan",
                                                     "NaN",
                                                     "inf",
                                                     "-inf",
                                                     "Infinity",
                                                     "-0",
                                                     "0",
                                                     "-1",
                                                     "4294967297",
                                                     "4294967295",
                                                     "2147483648",
                                                     "-2147483649",
                                                     "9223372036854775808",
                                                     "99999999999999999999999",
                                                     "1e-320",
                                                     "0x10",
                                                     "1e38",
                                                     "3.4e38",
                                                     "65536",
                                                     "255",
                                                     ""};
    return numbers;
}

/// Runs of characters that can belong to a number and contain a digit: [begin, end).
std::vector<std::pair<std::size_t, std::size_t>> number_spans(const std::string& s) {
    std::vector<std::pair<std::size_t, std::size_t>> spans;
    const auto numeric = [](char c) {
        return (c >= '0' && c <= '9') || c == '.' || c == '-' || c == '+' || c == 'e' || c == 'E';
    };
    for (std::size_t i = 0; i < s.size();) {
        if (!numeric(s[i])) {
            ++i;
            continue;
        }
        std::size_t j = i;
        bool digit = false;
        for (; j < s.size() && numeric(s[j]); ++j) digit = digit || (s[j] >= '0' && s[j] <= '9');
        if (digit) spans.emplace_back(i, j);
        i = j;
    }
    return spans;
}

/// Identifier-like words [begin, end) (tag, attribute, plugin and property names, keywords).
std::vector<std::pair<std::size_t, std::size_t>> word_spans(const std::string& s) {
    std::vector<std::pair<std::size_t, std::size_t>> spans;
    const auto letter = [](char c) {
        return (c >= 'a' && c <= 'z') || (c >= 'A' && c <= 'Z') || c == '_';
    };
    for (std::size_t i = 0; i < s.size();) {
        if (!letter(s[i])) {
            ++i;
            continue;
        }
        std::size_t j = i;
        while (j < s.size() && (letter(s[j]) || (s[j] >= '0' && s[j] <= '9'))) ++j;
        spans.emplace_back(i, j);
        i = j;
    }
    return spans;
}

/// One random mutation of `s`: a bit flip, an inserted byte (often a syntax character), an
/// erased or duplicated range, a number replaced by an interesting one, a word replaced by
/// another word of the corpus, or a range spliced in from another corpus file.
void mutate_once(std::string& s, const std::vector<std::string>& donors, FuzzRandom& random) {
    static const std::string syntax = "<>/\"'=&;$#!?-.0123456789eE \n\t,";
    const std::size_t size = s.size();
    switch (random.below(7)) {
        case 0:
            if (size > 0) s[random.below(size)] ^= static_cast<char>(1u << random.below(8));
            break;
        case 1: {
            const char c = random.below(2) == 0 ? syntax[random.below(syntax.size())]
                                                : static_cast<char>(random.below(256));
            s.insert(s.begin() + static_cast<std::ptrdiff_t>(random.below(size + 1)), c);
            break;
        }
        case 2:
            if (size > 0) s.erase(random.below(size), 1 + random.below(16));
            break;
        case 3:
            if (size > 0) {
                const std::string range = s.substr(random.below(size), 1 + random.below(64));
                s.insert(random.below(size + 1), range);
            }
            break;
        case 4: {
            const auto spans = number_spans(s);
            if (spans.empty()) break;
            const auto [begin, end] = spans[random.below(spans.size())];
            const auto& numbers = interesting_numbers();
            s.replace(begin, end - begin, numbers[random.below(numbers.size())]);
            break;
        }
        case 5: {
            const std::string& donor = donors[random.below(donors.size())];
            const auto targets = word_spans(s);
            const auto sources = word_spans(donor);
            if (targets.empty() || sources.empty()) break;
            const auto [begin, end] = targets[random.below(targets.size())];
            const auto [from, to] = sources[random.below(sources.size())];
            s.replace(begin, end - begin, donor.substr(from, to - from));
            break;
        }
        default: {
            const std::string& donor = donors[random.below(donors.size())];
            if (donor.empty()) break;
            const std::string range =
                donor.substr(random.below(donor.size()), 1 + random.below(128));
            s.insert(random.below(size + 1), range);
            break;
        }
    }
}

/// Aborts the process when one input runs longer than kHangSeconds (a hang would otherwise
/// only meet ctest's timeout, without saying which input).
class Watchdog {
  public:
    Watchdog()
        : thread_([this] {
              std::unique_lock lock(mutex_);
              while (!stop_) {
                  if (running_ && std::chrono::steady_clock::now() - started_ >
                                      std::chrono::duration<double>(kHangSeconds)) {
                      write_bytes(kept_, bytes_);
                      std::cerr << "fuzz input " << label_ << " ran longer than " << kHangSeconds
                                << " s (a hang); kept at " << kept_ << std::endl;
                      std::abort();
                  }
                  wake_.wait_for(lock, std::chrono::milliseconds(200));
              }
          }) {}
    ~Watchdog() {
        {
            std::lock_guard lock(mutex_);
            stop_ = true;
        }
        wake_.notify_all();
        thread_.join();
    }
    Watchdog(const Watchdog&) = delete;
    Watchdog& operator=(const Watchdog&) = delete;

    void start(const std::string& label, const std::string& kept, const std::string& bytes) {
        std::lock_guard lock(mutex_);
        label_ = label;
        kept_ = kept;
        bytes_ = bytes;
        started_ = std::chrono::steady_clock::now();
        running_ = true;
    }
    void done() {
        std::lock_guard lock(mutex_);
        running_ = false;
    }

  private:
    std::mutex mutex_;
    std::condition_variable wake_;
    bool stop_ = false;
    bool running_ = false;
    std::chrono::steady_clock::time_point started_;
    std::string label_, kept_, bytes_;
    std::thread thread_;
};

/// The corpus files of one loader, and how to load a file of that kind.
struct FuzzTarget {
    std::string name;
    std::string extension;
    std::vector<std::string> corpus;  // file names in tests/core/fuzz_corpus
    void (*load)(const std::string& path);
};

void load_scene_file(const std::string& path) {
    (void)build_scene(parse_scene_file(path));
}

void load_mesh_file(const std::string& path) {
    (void)load_mesh(path, FileLoc{"scene.xml", 7, 9});
}

/// The InputError messages the CLI prints must start with `file:line` (and usually `:column`).
bool names_file_and_line(const std::string& message) {
    static const std::regex located("^[^\n]+:[0-9]+(:[0-9]+)?: error: .*", std::regex::extended);
    return std::regex_search(message, located);
}

struct FuzzOutcome {
    int accepted = 0;
    int rejected = 0;
    int failures = 0;
    double seconds = 0.0;
};

/// Loads `mutants` mutants of `target`'s corpus (seed `seed`), the unmutated corpus first
/// (each must load: a corpus that is already rejected tests nothing).
FuzzOutcome fuzz(const FuzzTarget& target, std::uint64_t seed, int mutants) {
    const fs::path corpus_dir = fs::path(GDMLT_SOURCE_DIR) / "tests" / "core" / "fuzz_corpus";
    const fs::path dir = fs::temp_directory_path() /
                         ("gdmlt_fuzz_" + std::to_string(::getpid()) + "_" + target.name);
    fs::remove_all(dir);
    fs::create_directories(dir);
    // The scenes name the mesh files beside them: the unmutated corpus is there.
    for (const auto& entry : fs::directory_iterator(corpus_dir))
        fs::copy_file(entry.path(), dir / entry.path().filename());
    std::vector<std::string> originals;
    for (const std::string& name : target.corpus)
        originals.push_back(read_bytes(corpus_dir / name));
    for (std::size_t i = 0; i < originals.size(); ++i)
        EXPECT_NO_THROW(target.load((dir / target.corpus[i]).string()))
            << "corpus file " << target.corpus[i] << " does not load";

    FuzzOutcome outcome;
    FuzzRandom random(seed);
    Watchdog watchdog;
    const fs::path input = dir / ("fuzz." + target.extension);
    const auto start = std::chrono::steady_clock::now();
    for (int m = 0; m < mutants && outcome.failures < 10; ++m) {
        std::string bytes = originals[random.below(originals.size())];
        const std::size_t count = 1 + random.below(4);
        for (std::size_t k = 0; k < count; ++k) mutate_once(bytes, originals, random);
        write_bytes(input, bytes);
        const std::string label =
            target.name + " mutant " + std::to_string(m) + " (seed " + std::to_string(seed) + ")";
        const fs::path kept = dir.parent_path() / ("gdmlt_fuzz_failure_" + target.name + "_" +
                                                   std::to_string(m) + "." + target.extension);
        const auto keep = [&] {
            write_bytes(kept, bytes);
            ++outcome.failures;
        };
        watchdog.start(label, kept.string(), bytes);
        try {
            target.load(input.string());
            ++outcome.accepted;
        } catch (const InputError& e) {
            ++outcome.rejected;
            if (!names_file_and_line(e.what())) {
                keep();
                ADD_FAILURE() << label << ": InputError without file:line: " << e.what()
                              << "\n(input kept at " << kept.string() << ")";
            }
        } catch (const std::exception& e) {
            keep();
            ADD_FAILURE() << label << ": " << typeid(e).name() << ": " << e.what()
                          << "\n(input kept at " << kept.string() << ")";
        } catch (...) {
            keep();
            ADD_FAILURE() << label << ": non-standard exception (input kept at " << kept.string()
                          << ")";
        }
        watchdog.done();
    }
    outcome.seconds =
        std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    std::error_code ignored;
    fs::remove_all(dir, ignored);
    return outcome;
}

void report(const FuzzOutcome& outcome, int mutants) {
    std::cout << mutants << " mutants: " << outcome.accepted << " loaded, " << outcome.rejected
              << " rejected with InputError, " << outcome.failures << " failures, "
              << outcome.seconds << " s\n";
    ::testing::Test::RecordProperty("seconds", std::to_string(outcome.seconds));
    rusage usage{};
    ::getrusage(RUSAGE_SELF, &usage);
    EXPECT_LT(static_cast<double>(usage.ru_maxrss) * 1024.0, kPeakMemoryBytes)
        << "peak memory (a mutant made a loader allocate far more than its file holds)";
    // Most mutants must be rejected and some must load: otherwise the mutations never reach
    // past the first syntax check, or never break anything, and the run tests little.
    EXPECT_GT(outcome.accepted, mutants / 50);
    EXPECT_GT(outcome.rejected, mutants / 10);
}

// Seeds and counts are fixed: the same mutants on every run, so a failure is reproducible by
// its index. Counts are sized to the whole suite's budget of 20 s in the release build and 60 s
// under ASan/UBSan. Measured on a loaded 2-core machine: 1500 scenes 6.6 s release (about 4 ms
// each, mostly Embree's scene build) and 16 s ASan; 10000 OBJ files 1.5 s and 9.3 s, 10000 PLY
// files 1.0 s and 27 s, hence 6000 of each. The first runs found a crash (a PLY
// property before any element), a hang (an element of 2^40 items without properties) and a
// 4 GB allocation (a PLY list count of 10^9): see tests/core/test_mesh_io.cpp.

TEST(LoaderFuzz, SceneXmlMutantsLoadOrGiveLocatedInputErrors) {
    constexpr int kMutants = 1500;
    const FuzzTarget target{"xml", "xml", {"scene_v3.xml", "scene_v06.xml"}, load_scene_file};
    const FuzzOutcome outcome = fuzz(target, 15001, kMutants);
    report(outcome, kMutants);
}

TEST(LoaderFuzz, ObjMutantsLoadOrGiveLocatedInputErrors) {
    constexpr int kMutants = 6000;
    const FuzzTarget target{"obj", "obj", {"mesh.obj"}, load_mesh_file};
    const FuzzOutcome outcome = fuzz(target, 15002, kMutants);
    report(outcome, kMutants);
}

TEST(LoaderFuzz, PlyMutantsLoadOrGiveLocatedInputErrors) {
    constexpr int kMutants = 6000;
    const FuzzTarget target{"ply", "ply", {"mesh_ascii.ply", "mesh_binary.ply"}, load_mesh_file};
    const FuzzOutcome outcome = fuzz(target, 15003, kMutants);
    report(outcome, kMutants);
}

}  // namespace
}  // namespace gdmlt
