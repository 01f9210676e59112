# raykit::turbojpeg: libjpeg-turbo's TurboJPEG API (Debian libturbojpeg0-dev), which
# raykit/render/image_decode.hpp decodes JPEG textures with. It ships no CMake package, so
# this file finds it; raykit's build and its installed package config both include it.
if(NOT TARGET raykit::turbojpeg)
    find_path(RAYKIT_TURBOJPEG_INCLUDE_DIR turbojpeg.h)
    find_library(RAYKIT_TURBOJPEG_LIBRARY turbojpeg)
    if(NOT RAYKIT_TURBOJPEG_INCLUDE_DIR OR NOT RAYKIT_TURBOJPEG_LIBRARY)
        message(FATAL_ERROR "raykit needs TurboJPEG (libjpeg-turbo) for JPEG textures: on Debian, apt-get install libturbojpeg0-dev")
    endif()
    add_library(raykit::turbojpeg UNKNOWN IMPORTED GLOBAL)
    set_target_properties(raykit::turbojpeg PROPERTIES
        IMPORTED_LOCATION "${RAYKIT_TURBOJPEG_LIBRARY}"
        INTERFACE_INCLUDE_DIRECTORIES "${RAYKIT_TURBOJPEG_INCLUDE_DIR}")
endif()
