/// @file entry_reader.h
/// Private to the parameter readers: the fields of one entry of a list parameter (~colliders,
/// ~cameras), each checked for its type, every error naming the list, the entry and the field.
#pragma once

#include "deformable_flsm/runtime/node_params.h"

#include "xmlrpc_value.h"

#include <Eigen/Core>

#include <cmath>
#include <sstream>
#include <string>
#include <vector>

namespace deformable_flsm {

class EntryReader {
 public:
  /// @param[in] entry   the entry (a dictionary)
  /// @param[in] list    the parameter it is in, as the user writes it ("~colliders")
  /// @param[in] index   its place in the list
  /// @param[in] fields  the fields an entry may have
  EntryReader(XmlRpc::XmlRpcValue& entry, std::string list, int index, const std::vector<std::string>& fields)
      : entry_(entry), list_(std::move(list)), index_(index), fields_(fields) {}

  [[noreturn]] void fail(const std::string& what) const {
    std::ostringstream out;
    out << list_ << " entry " << index_;
    if (!id_.empty()) out << " ('" << id_ << "')";
    out << ": " << what;
    throw ParamError(out.str());
  }
  /// The entry's name, named in every error from now on.
  void setId(const std::string& id) { id_ = id; }

  bool has(const char* field) { return entry_.hasMember(field); }

  std::string string(const char* field, const std::string& fallback) {
    if (!has(field)) return fallback;
    XmlRpc::XmlRpcValue& v = entry_[field];
    if (v.getType() != XmlRpc::XmlRpcValue::TypeString)
      fail(std::string(field) + " is " + describe(v) + ": it must be a string");
    return static_cast<std::string&>(v);
  }

  double number(const char* field, double fallback) {
    if (!has(field)) return fallback;
    double out = 0.0;
    if (!toNumber(entry_[field], out) || !std::isfinite(out))
      fail(std::string(field) + " is " + describe(entry_[field]) + ": it must be a finite number");
    return out;
  }

  /// A whole number in [lo, hi] (YAML's 3 or 3.0), else the entry fails saying so.
  int integer(const char* field, int fallback, int lo, int hi) {
    const double v = number(field, fallback);
    if (v != std::floor(v) || v < lo || v > hi)
      fail(std::string(field) + " is " + std::to_string(v) + ": it must be a whole number from " +
           std::to_string(lo) + " to " + std::to_string(hi));
    return static_cast<int>(v);
  }

  Eigen::VectorXd numbers(const char* field, int count, const Eigen::VectorXd& fallback) {
    if (!has(field)) return fallback;
    XmlRpc::XmlRpcValue& v = entry_[field];
    Eigen::VectorXd out(count);
    bool ok = v.getType() == XmlRpc::XmlRpcValue::TypeArray && v.size() == count;
    for (int k = 0; ok && k < count; ++k) ok = toNumber(v[k], out[k]) && std::isfinite(out[k]);
    if (!ok)
      fail(std::string(field) + " is " + describe(v) + ": it must be a list of " +
           std::to_string(count) + " finite numbers");
    return out;
  }

  /// Fails on a field the entry may not have (a typo), listing those it may.
  void checkFields() {
    for (auto it = entry_.begin(); it != entry_.end(); ++it) {
      bool known = false;
      for (const std::string& f : fields_) known = known || it->first == f;
      if (!known) {
        std::string all;
        for (const std::string& f : fields_) all += (all.empty() ? "" : ", ") + f;
        fail("unknown field '" + it->first + "' (misspelt?): the fields are " + all);
      }
    }
  }

 private:
  XmlRpc::XmlRpcValue& entry_;
  std::string list_;
  int index_;
  std::vector<std::string> fields_;
  std::string id_;
};

}  // namespace deformable_flsm
