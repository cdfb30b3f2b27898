// placeholder while the file is written
