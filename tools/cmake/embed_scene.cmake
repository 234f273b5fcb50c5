# cmake -DIN=scene -DOUT=header -DNAME=name -P embed_scene.cmake: the scene text as a C array,
# byte by byte, so that no quoting of the text can go wrong.
file(READ ${IN} hex HEX)
string(REGEX REPLACE "([0-9a-f][0-9a-f])" "0x\\1," bytes "${hex}")
file(WRITE ${OUT} "/* Generated from ${IN}: do not edit. */\n#pragma once\n"
  "#define DS_DEFAULT_SCENE_NAME \"${NAME}\"\n"
  "static const char ds_default_scene_text[] = { ${bytes} 0x00 };\n")
