// A Pinocchio model handed over from Python as its own serialisation (Model.saveToString): the Python bindings'
// objects are Boost.Python's, not this module's, so the model crosses as text (exact: Boost's text archive writes
// doubles with 17 significant digits).
#pragma once

#include <pinocchio/algorithm/crba.hpp>
#include <pinocchio/algorithm/rnea.hpp>
#include <pinocchio/multibody.hpp>
#include <pinocchio/serialization.hpp>

#include <stdexcept>
#include <string>

namespace dynid {

inline pinocchio::Model load_model(const std::string& serialized) {
    pinocchio::Model m;
    try {
        m.loadFromString(serialized);
    } catch (const std::exception& e) {
        throw std::invalid_argument(std::string("not a serialised Pinocchio model: ") + e.what());
    }
    return m;
}

}  // namespace dynid
