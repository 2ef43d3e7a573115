# cmake -DINPUT=file.bin -DOUTPUT=file.cpp -DSYMBOL=kName -P EmbedFile.cmake
# Writes a C++ source defining `extern const unsigned char SYMBOL[]` and
# `extern const std::size_t SYMBOLSize` with the bytes of INPUT (empty when
# INPUT does not exist, e.g. before the first scripts/build-atlas).
if(EXISTS "${INPUT}")
  file(READ "${INPUT}" hex HEX)
else()
  set(hex "")
endif()
string(LENGTH "${hex}" n)
math(EXPR bytes "${n} / 2")
string(REGEX REPLACE "([0-9a-f][0-9a-f])" "0x\\1," body "${hex}")
string(REGEX REPLACE "((0x[0-9a-f][0-9a-f],){32})" "\\1\n" body "${body}")
file(WRITE "${OUTPUT}" "// Generated from ${INPUT} by cmake/EmbedFile.cmake; do not edit.\n#include <cstddef>\n"
  "extern const unsigned char ${SYMBOL}Data[] = {\n${body}0x00};\n"
  "extern const std::size_t ${SYMBOL}Size = ${bytes};\n")
