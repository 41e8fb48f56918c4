/// @file csv.h
/// The CSV files of the speed/accuracy study (flsm_study): numbers as they are written, and
/// rows merged with those of an existing file (--methods) and sorted by scenario and method.
#pragma once

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <iomanip>
#include <sstream>
#include <string>
#include <vector>

namespace deformable_flsm {
namespace study {

/// A number as the CSV files write it: 6 significant digits, "" for NaN, "inf" for infinity.
inline std::string num(double v) {
  if (std::isnan(v)) return "";
  if (std::isinf(v)) return "inf";
  std::ostringstream os;
  os << std::setprecision(6) << v;
  return os.str();
}

/// Can the rows of the file at `path` be merged with this program's (`header`)? True when the
/// file is missing or empty or starts with `header`; otherwise prints why not.
inline bool mergeable(const std::string& path, const std::string& header) {
  std::ifstream in(path);
  std::string line;
  if (!in || !std::getline(in, line) || line == header) return true;
  std::fprintf(stderr, "flsm_study: %s has other columns than this program writes: run the whole study "
                       "(without --methods) once\n", path.c_str());
  return false;
}

/// How writeCsv() orders rows: by scenario (kScenarioOrder), then method (its `methodOrder`,
/// flsm_study's kAllMethods); or by method only. Rows of equal rank keep the order in which they
/// were run.
enum class CsvOrder { ScenarioThenMethod, Method };
inline const std::vector<std::string> kScenarioOrder = {"cantilever", "column", "ear-drag", "drag-5x", "plane", "scrambled"};

/// Field `k` (from 0) of a CSV line without quoted fields.
inline std::string csvField(const std::string& line, int k) {
  std::size_t begin = 0;
  for (int i = 0; i < k; ++i) {
    begin = line.find(',', begin);
    if (begin == std::string::npos) return {};
    ++begin;
  }
  return line.substr(begin, line.find(',', begin) - begin);
}

/// Writes `header` and `lines` (rows without newline; field 0 the scenario, field 1 the method)
/// to `path`. With `keepOthers`, the rows of the existing file whose method this run did not run
/// (`ran` false) are kept; an existing file with another header cannot be merged (its columns
/// differ): that is an error that asks for the whole study. Rows are sorted by `order`, methods
/// ranked by `methodOrder`. Returns false after printing why.
template <typename Ran>
bool writeCsv(const std::string& path, const std::string& header, std::vector<std::string> lines, bool keepOthers,
              const Ran& ran, const std::vector<std::string>& methodOrder, CsvOrder order) {
  if (keepOthers) {
    if (!mergeable(path, header)) return false;
    std::ifstream in(path);
    std::string line;
    if (in && std::getline(in, line)) {
      while (std::getline(in, line))
        if (!line.empty() && !ran(csvField(line, 1))) lines.push_back(line);
    }
  }
  auto rank = [](const std::vector<std::string>& list, const std::string& name) {
    return std::find(list.begin(), list.end(), name) - list.begin();
  };
  std::stable_sort(lines.begin(), lines.end(), [&](const std::string& a, const std::string& b) {
    const auto ma = rank(methodOrder, csvField(a, 1)), mb = rank(methodOrder, csvField(b, 1));
    if (order == CsvOrder::Method) return ma < mb;
    const auto sa = rank(kScenarioOrder, csvField(a, 0)), sb = rank(kScenarioOrder, csvField(b, 0));
    return sa != sb ? sa < sb : ma < mb;
  });
  std::ofstream f(path);
  if (!f) {
    std::fprintf(stderr, "flsm_study: cannot write %s (does the directory exist?)\n", path.c_str());
    return false;
  }
  f << header << '\n';
  for (const std::string& line : lines) f << line << '\n';
  return true;
}

}  // namespace study
}  // namespace deformable_flsm
