# KTSundials.cmake -- provides SUNDIALS (CVODE, version 6 API) for KevlarTether.
#
# Results:
#   target  kt_sundials                     INTERFACE: include dir + static CVODE libraries (by path)
#   var     KT_SUNDIALS_SOURCE_DIR          unpacked SUNDIALS source tree (for packaging sources/ into
#                                           the FMU); empty when KT_FMU_SOURCES is OFF
#   var     KT_SUNDIALS_GENERATED_INCLUDE   dir holding the CMake-generated sundials/sundials_config.h
#                                           and sundials/sundials_export.h that match that source tree
#   var     KT_SUNDIALS_VERSION             e.g. 6.4.1
#
# Two modes:
#   default                 the Debian source package's upstream tarball (sundials_*.orig.tar.xz) is
#                           downloaded once with a private, root-free apt configuration
#                           (cmake/fetch_debian_source.py), cached in KT_DEPS_DIR (.deps/), unpacked,
#                           configured and built with SUNDIALS' own CMake at configure time (static, PIC,
#                           serial, CVODE only) and installed to <build>/_deps/sundials-install.
#   -DKT_SUNDIALS_ROOT=DIR  link DIR/lib*/libsundials_*.a of your own install (must be static: the FMU
#                           binary may depend on libc/libm only). The FMU's sources/ still needs SUNDIALS'
#                           source, so the tarball is fetched and *configured* (not built) as above; if that
#                           is impossible (offline), add -DKT_FMU_SOURCES=OFF to package an FMU without
#                           sources/ (then `fmpy compile` cannot rebuild it).
#   -DKT_SUNDIALS_TARBALL=F use this upstream tarball instead of downloading one (offline builds).

set(KT_SUNDIALS_ROOT "" CACHE PATH "Use this SUNDIALS 6 install prefix (static libs) instead of building SUNDIALS from source")
set(KT_SUNDIALS_TARBALL "" CACHE FILEPATH "SUNDIALS upstream source tarball to use instead of downloading the Debian one")
set(KT_DEPS_DIR "${PROJECT_SOURCE_DIR}/.deps" CACHE PATH "Download cache for third-party sources")

set(_kt_deps_build "${CMAKE_BINARY_DIR}/_deps")
set(_kt_sun_install "${_kt_deps_build}/sundials-install")
set(_kt_sun_build "${_kt_deps_build}/sundials-build")

# ---------------------------------------------------------------------------------------------
# 1. the source tarball (needed unless we link a user install AND package no sources)
# ---------------------------------------------------------------------------------------------
set(_kt_need_source ON)
if(KT_SUNDIALS_ROOT AND NOT KT_FMU_SOURCES)
  set(_kt_need_source OFF)
endif()

set(KT_SUNDIALS_SOURCE_DIR "")
set(KT_SUNDIALS_GENERATED_INCLUDE "")

if(_kt_need_source)
  if(KT_SUNDIALS_TARBALL)
    if(NOT EXISTS "${KT_SUNDIALS_TARBALL}")
      message(FATAL_ERROR "KT_SUNDIALS_TARBALL=${KT_SUNDIALS_TARBALL} does not exist")
    endif()
    set(_kt_tarball "${KT_SUNDIALS_TARBALL}")
  else()
    file(GLOB _kt_cached "${KT_DEPS_DIR}/sundials_*.orig.tar.*")
    list(FILTER _kt_cached EXCLUDE REGEX "\\.(asc|part)$")
    if(_kt_cached)
      list(SORT _kt_cached)
      list(GET _kt_cached -1 _kt_tarball)
      message(STATUS "SUNDIALS: using cached source ${_kt_tarball}")
    else()
      message(STATUS "SUNDIALS: downloading the Debian source package 'sundials' into ${KT_DEPS_DIR} (private apt config, no root)")
      execute_process(
        COMMAND "${Python3_EXECUTABLE}" "${PROJECT_SOURCE_DIR}/cmake/fetch_debian_source.py"
                sundials "${KT_DEPS_DIR}" "${_kt_deps_build}/apt-state"
        RESULT_VARIABLE _kt_rc
        OUTPUT_VARIABLE _kt_out
        ERROR_VARIABLE _kt_err)
      if(NOT _kt_rc EQUAL 0)
        message(FATAL_ERROR
          "SUNDIALS: could not download the SUNDIALS source with apt-get (exit ${_kt_rc}).\n"
          "${_kt_err}\n"
          "Fixes: check the network to the Debian mirror and re-run; or put a SUNDIALS 6 upstream "
          "tarball at ${KT_DEPS_DIR}/sundials_<version>.orig.tar.xz or pass -DKT_SUNDIALS_TARBALL=FILE; "
          "or link your own static install with -DKT_SUNDIALS_ROOT=PREFIX -DKT_FMU_SOURCES=OFF.")
      endif()
      string(STRIP "${_kt_out}" _kt_out)
      string(REGEX REPLACE ".*\n" "" _kt_tarball "${_kt_out}")
      if(NOT EXISTS "${_kt_tarball}")
        message(FATAL_ERROR "SUNDIALS: the download reported '${_kt_tarball}', which does not exist.\n${_kt_out}\n${_kt_err}")
      endif()
      message(STATUS "SUNDIALS: downloaded ${_kt_tarball}")
    endif()
  endif()

  # unpack (once per tarball)
  get_filename_component(_kt_tarname "${_kt_tarball}" NAME)
  set(_kt_unpack_stamp "${_kt_deps_build}/sundials-src.stamp")
  set(_kt_unpack_dir "${_kt_deps_build}/sundials-src")
  set(_kt_stamp_text "")
  if(EXISTS "${_kt_unpack_stamp}")
    file(READ "${_kt_unpack_stamp}" _kt_stamp_text)
  endif()
  if(NOT _kt_stamp_text STREQUAL "${_kt_tarname}")
    file(REMOVE_RECURSE "${_kt_unpack_dir}" "${_kt_sun_build}" "${_kt_sun_install}" "${_kt_deps_build}/sundials-build.stamp")
    file(MAKE_DIRECTORY "${_kt_unpack_dir}")
    execute_process(COMMAND "${CMAKE_COMMAND}" -E tar xf "${_kt_tarball}"
                    WORKING_DIRECTORY "${_kt_unpack_dir}" RESULT_VARIABLE _kt_rc)
    if(NOT _kt_rc EQUAL 0)
      message(FATAL_ERROR "SUNDIALS: could not unpack ${_kt_tarball} (corrupt download? delete it and re-run)")
    endif()
    file(WRITE "${_kt_unpack_stamp}" "${_kt_tarname}")
  endif()
  file(GLOB _kt_top LIST_DIRECTORIES true "${_kt_unpack_dir}/*")
  set(KT_SUNDIALS_SOURCE_DIR "")
  foreach(_d IN LISTS _kt_top)
    if(EXISTS "${_d}/include/cvode/cvode.h" AND EXISTS "${_d}/src/cvode/cvode.c")
      set(KT_SUNDIALS_SOURCE_DIR "${_d}")
    endif()
  endforeach()
  if(NOT KT_SUNDIALS_SOURCE_DIR)
    message(FATAL_ERROR "SUNDIALS: ${_kt_tarball} does not look like a SUNDIALS source tree (no include/cvode/cvode.h)")
  endif()

  # configure (and, in the default mode, build + install) with SUNDIALS' own CMake, once per
  # tarball + option set
  set(_kt_sun_args
    -DCMAKE_BUILD_TYPE=Release
    "-DCMAKE_C_COMPILER=${CMAKE_C_COMPILER}"
    "-DCMAKE_C_FLAGS=-fvisibility=hidden"
    -DCMAKE_POSITION_INDEPENDENT_CODE=ON
    -DBUILD_SHARED_LIBS=OFF -DBUILD_STATIC_LIBS=ON
    -DBUILD_CVODE=ON
    -DBUILD_ARKODE=OFF -DBUILD_CVODES=OFF -DBUILD_IDA=OFF -DBUILD_IDAS=OFF -DBUILD_KINSOL=OFF
    -DENABLE_MPI=OFF -DENABLE_OPENMP=OFF -DENABLE_PTHREAD=OFF -DENABLE_LAPACK=OFF
    -DBUILD_FORTRAN_MODULE_INTERFACE=OFF
    -DEXAMPLES_ENABLE_C=OFF -DEXAMPLES_ENABLE_CXX=OFF -DEXAMPLES_INSTALL=OFF
    -DSUNDIALS_INDEX_SIZE=64 -DSUNDIALS_PRECISION=double
    "-DCMAKE_INSTALL_PREFIX=${_kt_sun_install}"
    -DCMAKE_INSTALL_LIBDIR=lib)
  if(KT_SUNDIALS_ROOT)
    set(_kt_sun_mode "configure")
  else()
    set(_kt_sun_mode "build")
  endif()
  string(REPLACE ";" " " _kt_sun_key "${_kt_tarname} ${_kt_sun_mode} ${CMAKE_GENERATOR} ${_kt_sun_args}")
  set(_kt_build_stamp "${_kt_deps_build}/sundials-build.stamp")
  set(_kt_stamp_text "")
  if(EXISTS "${_kt_build_stamp}")
    file(READ "${_kt_build_stamp}" _kt_stamp_text)
  endif()
  if(NOT _kt_stamp_text STREQUAL "${_kt_sun_key}")
    file(REMOVE_RECURSE "${_kt_sun_build}" "${_kt_sun_install}")
    string(TIMESTAMP _kt_t0 "%s")
    message(STATUS "SUNDIALS: configuring ${KT_SUNDIALS_SOURCE_DIR} (log: ${_kt_deps_build}/sundials-*.log)")
    execute_process(
      COMMAND "${CMAKE_COMMAND}" -S "${KT_SUNDIALS_SOURCE_DIR}" -B "${_kt_sun_build}" -G "${CMAKE_GENERATOR}" ${_kt_sun_args}
      RESULT_VARIABLE _kt_rc OUTPUT_FILE "${_kt_deps_build}/sundials-configure.log" ERROR_FILE "${_kt_deps_build}/sundials-configure.err.log")
    if(NOT _kt_rc EQUAL 0)
      message(FATAL_ERROR "SUNDIALS: configure failed, see ${_kt_deps_build}/sundials-configure.err.log")
    endif()
    if(_kt_sun_mode STREQUAL "build")
      include(ProcessorCount)
      ProcessorCount(_kt_ncpu)
      if(_kt_ncpu EQUAL 0)
        set(_kt_ncpu 2)
      endif()
      message(STATUS "SUNDIALS: building and installing to ${_kt_sun_install}")
      execute_process(
        COMMAND "${CMAKE_COMMAND}" --build "${_kt_sun_build}" --parallel ${_kt_ncpu}
        RESULT_VARIABLE _kt_rc OUTPUT_FILE "${_kt_deps_build}/sundials-build.log" ERROR_FILE "${_kt_deps_build}/sundials-build.err.log")
      if(NOT _kt_rc EQUAL 0)
        message(FATAL_ERROR "SUNDIALS: build failed, see ${_kt_deps_build}/sundials-build.log")
      endif()
      execute_process(
        COMMAND "${CMAKE_COMMAND}" --install "${_kt_sun_build}"
        RESULT_VARIABLE _kt_rc OUTPUT_FILE "${_kt_deps_build}/sundials-install.log" ERROR_FILE "${_kt_deps_build}/sundials-install.err.log")
      if(NOT _kt_rc EQUAL 0)
        message(FATAL_ERROR "SUNDIALS: install failed, see ${_kt_deps_build}/sundials-install.err.log")
      endif()
    endif()
    string(TIMESTAMP _kt_t1 "%s")
    math(EXPR _kt_dt "${_kt_t1} - ${_kt_t0}")
    message(STATUS "SUNDIALS: ${_kt_sun_mode} done in ${_kt_dt} s")
    file(WRITE "${_kt_build_stamp}" "${_kt_sun_key}")
  endif()
  set(KT_SUNDIALS_GENERATED_INCLUDE "${_kt_sun_build}/include")
  if(NOT EXISTS "${KT_SUNDIALS_GENERATED_INCLUDE}/sundials/sundials_config.h")
    message(FATAL_ERROR "SUNDIALS: ${KT_SUNDIALS_GENERATED_INCLUDE}/sundials/sundials_config.h was not generated; delete ${_kt_deps_build} and re-run")
  endif()
endif()

# ---------------------------------------------------------------------------------------------
# 2. the libraries we link
# ---------------------------------------------------------------------------------------------
if(KT_SUNDIALS_ROOT)
  set(_kt_prefix "${KT_SUNDIALS_ROOT}")
else()
  set(_kt_prefix "${_kt_sun_install}")
endif()
if(NOT EXISTS "${_kt_prefix}/include/cvode/cvode.h")
  message(FATAL_ERROR "SUNDIALS: ${_kt_prefix}/include/cvode/cvode.h not found (KT_SUNDIALS_ROOT must be an install prefix)")
endif()
file(STRINGS "${_kt_prefix}/include/sundials/sundials_config.h" _kt_ver REGEX "^#define SUNDIALS_VERSION \"")
string(REGEX REPLACE ".*\"([^\"]*)\".*" "\\1" KT_SUNDIALS_VERSION "${_kt_ver}")
if(NOT KT_SUNDIALS_VERSION MATCHES "^6\\.")
  message(FATAL_ERROR "SUNDIALS: ${_kt_prefix} is version '${KT_SUNDIALS_VERSION}'; KevlarTether needs the SUNDIALS 6 API")
endif()

# order matters for static linking: the packages before what they use
set(_kt_libs cvode sunnonlinsolfixedpoint sunnonlinsolnewton sunlinsoldense sunmatrixdense nvecserial)
set(_kt_lib_paths "")
foreach(_l IN LISTS _kt_libs)
  unset(_kt_found CACHE)
  find_library(_kt_found NAMES "libsundials_${_l}.a"
               PATHS "${_kt_prefix}" PATH_SUFFIXES lib lib64 lib/x86_64-linux-gnu NO_DEFAULT_PATH)
  if(NOT _kt_found)
    if(_l STREQUAL "cvode")
      message(FATAL_ERROR "SUNDIALS: ${_kt_prefix}/lib*/libsundials_cvode.a not found. The FMU must not depend on "
                          "shared SUNDIALS libraries: build SUNDIALS with -DBUILD_STATIC_LIBS=ON -DCMAKE_POSITION_INDEPENDENT_CODE=ON")
    endif()
    # SUNDIALS 6 bundles these modules into libsundials_cvode.a as well; separate archives are optional
  else()
    list(APPEND _kt_lib_paths "${_kt_found}")
  endif()
  unset(_kt_found CACHE)
endforeach()

add_library(kt_sundials INTERFACE)
# SYSTEM: SUNDIALS headers are not subject to our -Werror/-pedantic flags
target_include_directories(kt_sundials SYSTEM INTERFACE "${_kt_prefix}/include")
target_link_libraries(kt_sundials INTERFACE ${_kt_lib_paths} m)
message(STATUS "SUNDIALS ${KT_SUNDIALS_VERSION}: ${_kt_prefix}")
