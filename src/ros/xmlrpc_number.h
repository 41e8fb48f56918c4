/// @file xmlrpc_number.h
/// Private to the parameter readers.
#pragma once

#include <xmlrpcpp/XmlRpcValue.h>

namespace deformable_flsm {

/// A number from an XML-RPC value that is an int or a double (YAML's 1 and 1.0); false for any
/// other type, `out` then unchanged.
inline bool toNumber(XmlRpc::XmlRpcValue& v, double& out) {
  if (v.getType() == XmlRpc::XmlRpcValue::TypeDouble) {
    out = static_cast<double>(v);
    return true;
  }
  if (v.getType() == XmlRpc::XmlRpcValue::TypeInt) {
    out = static_cast<int>(v);
    return true;
  }
  return false;
}

}  // namespace deformable_flsm
