# cmake -DIN=file -DOUT=header -DSYMBOL=name -P embed_text.cmake: a text file as a C array,
# byte by byte (no quoting of the text can go wrong), NUL-terminated: `static const char SYMBOL[]`.
file(READ ${IN} hex HEX)
string(REGEX REPLACE "([0-9a-f][0-9a-f])" "0x\\1," bytes "${hex}")
file(WRITE ${OUT} "/* Generated from ${IN}: do not edit. */\n#pragma once\n"
  "static const char ${SYMBOL}[] = { ${bytes} 0x00 };\n")
