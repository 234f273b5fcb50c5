# cmake -DIN=file -DOUT=header -P embed_text.cmake: labsim's GenICam XML as a C string
# (ds_labsim_camera_xml), byte by byte, so that no quoting can go wrong.
file(READ ${IN} hex HEX)
string(REGEX REPLACE "([0-9a-f][0-9a-f])" "0x\\1," bytes "${hex}")
file(WRITE ${OUT} "/* Generated from ${IN}: do not edit. */\n#pragma once\n"
  "static const char ds_labsim_camera_xml[] = { ${bytes} 0x00 };\n")
