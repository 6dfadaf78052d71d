#include "bindings.hpp"
namespace dynid { void register_plant(nb::module_&) {} }
