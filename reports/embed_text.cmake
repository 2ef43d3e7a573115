# cmake -DINPUT=file -DOUTPUT=header -DNAME=identifier -P embed_text.cmake
# Writes a header defining `inline constexpr const char NAME[]` with INPUT's
# text as a raw string literal (the report's viewer script, the pages' stylesheet).
file(READ "${INPUT}" text)
set(delim "mandisym_embed")
string(FIND "${text}" ")${delim}\"" clash)
if(NOT clash EQUAL -1)
  message(FATAL_ERROR "${INPUT} contains the raw-string delimiter )${delim}\"")
endif()
set(body "// Generated from ${INPUT} by embed_text.cmake; do not edit.\n#pragma once\n\ninline constexpr const char ${NAME}[] = R\"${delim}(${text})${delim}\";\n")
if(EXISTS "${OUTPUT}")
  file(READ "${OUTPUT}" old)
  if(old STREQUAL body)
    return()
  endif()
endif()
file(WRITE "${OUTPUT}" "${body}")
