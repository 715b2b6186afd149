"""A raw CAN log (candump, Vector ASC/BLF, python-can CSV) decoded with a DBC into wheel and
IMU streams."""
