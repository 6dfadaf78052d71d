#include "pinocchio_model.hpp"

#include <pinocchio/serialization.hpp>

#include <stdexcept>

namespace dynid {

pinocchio::Model load_model(const std::string& serialized) {
    pinocchio::Model m;
    try {
        m.loadFromString(serialized);
    } catch (const std::exception& e) {
        throw std::invalid_argument(std::string("not a serialised Pinocchio model: ") + e.what());
    }
    return m;
}

}  // namespace dynid
