# mandisym_module(NAME SOURCES ... DEPS ... [ITK])
# One static library per pipeline stage. Public include root is modules/ so that
# code includes "io/volume_io.h", "surface/surface.h", ...
# ITK: the stage talks to ITK; ITK include dirs are added PRIVATE to it alone.
function(mandisym_module name)
  cmake_parse_arguments(M "ITK" "" "SOURCES;DEPS" ${ARGN})
  add_library(ms_${name} STATIC ${M_SOURCES})
  target_include_directories(ms_${name} PUBLIC ${PROJECT_SOURCE_DIR}/modules ${PROJECT_SOURCE_DIR})
  target_compile_options(ms_${name} PRIVATE -Wall -Wextra)
  if(M_ITK)
    target_include_directories(ms_${name} SYSTEM PRIVATE ${ITK_INCLUDE_DIRS} ${ITKGDCM_INCLUDE_DIRS})
    target_link_libraries(ms_${name} PRIVATE ${ITK_LIBRARIES} ${ITKGDCM_LIBRARIES})
  endif()
  if(M_DEPS)
    target_link_libraries(ms_${name} PUBLIC ${M_DEPS})
  endif()
endfunction()
