/// @file xmlrpc_value.h
/// Private to the parameter readers: numbers from the parameter server, and what was found there
/// in words for error messages.
#pragma once

#include <xmlrpcpp/XmlRpcValue.h>

#include <sstream>
#include <string>

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

/// What was found on the parameter server, for error messages: "'fast' (a string)"; a short list
/// by its elements, "[1, 2, nan]", so that the one at fault shows.
inline std::string describe(XmlRpc::XmlRpcValue value) {
  std::ostringstream out;
  switch (value.getType()) {
    case XmlRpc::XmlRpcValue::TypeString:
      out << "'" << static_cast<std::string&>(value) << "' (a string)";
      break;
    case XmlRpc::XmlRpcValue::TypeBoolean:
      out << (static_cast<bool&>(value) ? "true" : "false") << " (a boolean)";
      break;
    case XmlRpc::XmlRpcValue::TypeArray:
      if (value.size() > 12) {
        out << "a list of " << value.size();
        break;
      }
      out << "[";
      for (int k = 0; k < value.size(); ++k) {
        double number = 0.0;
        out << (k > 0 ? ", " : "");
        if (toNumber(value[k], number))
          out << number;
        else if (value[k].getType() == XmlRpc::XmlRpcValue::TypeString)
          out << "'" << static_cast<std::string&>(value[k]) << "'";
        else
          out << describe(value[k]);
      }
      out << "]";
      break;
    case XmlRpc::XmlRpcValue::TypeStruct:
      out << "a dictionary";
      break;
    default:
      value.write(out);
  }
  return out.str();
}

}  // namespace deformable_flsm
