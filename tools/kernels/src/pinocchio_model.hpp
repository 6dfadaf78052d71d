// A Pinocchio model handed over from Python as its own serialisation (Model.saveToString): the Python bindings'
// objects are Boost.Python's, not this module's, so the model crosses as text (exact: Boost's text archive writes
// doubles with 17 significant digits).
#pragma once

#include <pinocchio/multibody.hpp>

#include <string>

namespace dynid {

// The model in `serialized`; std::invalid_argument if it is not one. Defined in its own translation unit: Boost's
// serialisation of a whole Model is the heaviest template instantiation of the module, made once, not per user.
pinocchio::Model load_model(const std::string& serialized);

}  // namespace dynid
