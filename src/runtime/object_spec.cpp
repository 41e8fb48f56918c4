#include "deformable_flsm/runtime/object_spec.h"

#include <cctype>

namespace deformable_flsm {

bool validObjectName(const std::string& name) {
  if (name.empty() || name.size() > ObjectLimits::kMaxNameLength) return false;
  if (!std::isalpha(static_cast<unsigned char>(name[0]))) return false;
  for (const char c : name)
    if (!std::isalnum(static_cast<unsigned char>(c)) && c != '_') return false;
  return true;
}

ObjectSpec singleObject(const NodeParams& params) {
  ObjectSpec spec;
  spec.name = params.objectFrameId;
  spec.params = params;
  return spec;
}

}  // namespace deformable_flsm
