# Warnings for our own targets only; third-party headers come in through imported targets and
# are therefore SYSTEM includes. Errors only when GDMLT_WERROR is on (CI), so research spikes
# are not blocked locally.
function(gdmlt_set_warnings target)
  target_compile_options(${target} PRIVATE -Wall -Wextra -Wpedantic -Wshadow -Wnon-virtual-dtor
                                           -Wcast-align -Wunused -Woverloaded-virtual)
  if(GDMLT_WERROR)
    target_compile_options(${target} PRIVATE -Werror)
  endif()
endfunction()

# A module library gdmlt::<name>: every .cpp below its folder (CONFIGURE_DEPENDS so new files are
# picked up); the include root is the repository top, so includes read "core/math/types.h".
#   gdmlt_add_module(core PUBLIC Eigen3::Eigen PRIVATE embree)
function(gdmlt_add_module name)
  cmake_parse_arguments(ARG "" "" "PUBLIC;PRIVATE" ${ARGN})
  file(GLOB_RECURSE sources CONFIGURE_DEPENDS ${CMAKE_CURRENT_SOURCE_DIR}/*.cpp)
  # Sources under a plugins/ folder are modules loaded at run time, built by their own targets.
  list(FILTER sources EXCLUDE REGEX "/plugins/")
  if(sources)
    add_library(gdmlt_${name} STATIC ${sources})
    target_include_directories(gdmlt_${name} PUBLIC ${PROJECT_SOURCE_DIR})
    target_link_libraries(gdmlt_${name} PUBLIC ${ARG_PUBLIC} PRIVATE ${ARG_PRIVATE})
    gdmlt_set_warnings(gdmlt_${name})
  else()
    # A module that has only headers so far.
    add_library(gdmlt_${name} INTERFACE)
    target_include_directories(gdmlt_${name} INTERFACE ${PROJECT_SOURCE_DIR})
    target_link_libraries(gdmlt_${name} INTERFACE ${ARG_PUBLIC})
  endif()
  add_library(gdmlt::${name} ALIAS gdmlt_${name})
endfunction()
