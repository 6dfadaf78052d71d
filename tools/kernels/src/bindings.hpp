// Shared helpers of the nanobind module: array types and shape checks (a wrong shape is a ValueError, never UB).
#pragma once

#include <nanobind/nanobind.h>
#include <nanobind/ndarray.h>

#include <stdexcept>
#include <string>

namespace dynid {

namespace nb = nanobind;
using CArray1 = nb::ndarray<const double, nb::ndim<1>, nb::c_contig, nb::device::cpu>;
using CArray2 = nb::ndarray<const double, nb::ndim<2>, nb::c_contig, nb::device::cpu>;
using Array1 = nb::ndarray<double, nb::ndim<1>, nb::c_contig, nb::device::cpu>;
using Array2 = nb::ndarray<double, nb::ndim<2>, nb::device::cpu>;
using CArray2Out = nb::ndarray<double, nb::ndim<2>, nb::c_contig, nb::device::cpu>;
using Array3 = nb::ndarray<double, nb::ndim<3>, nb::device::cpu>;

// rows of a (N, cols) array; cols < 0: any
inline long rows_of(const CArray2& a, const char* name, long cols) {
    if (cols >= 0 && a.shape(1) != static_cast<size_t>(cols))
        throw std::invalid_argument(std::string(name) + ": expected " + std::to_string(cols) + " columns");
    return static_cast<long>(a.shape(0));
}

inline void same_shape(const CArray2& a, const CArray2& ref, const char* name) {
    if (a.shape(0) != ref.shape(0) || a.shape(1) != ref.shape(1))
        throw std::invalid_argument(std::string(name) + ": shape differs from q's");
}

inline void shape2(const CArray2& a, long n, long cols, const char* name) {
    if (a.shape(0) != static_cast<size_t>(n) || a.shape(1) != static_cast<size_t>(cols))
        throw std::invalid_argument(std::string(name) + ": expected (" + std::to_string(n) + ", " +
                                    std::to_string(cols) + ")");
}

void register_observer(nb::module_& m);
void register_plant(nb::module_& m);

}  // namespace dynid
