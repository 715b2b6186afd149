"""A GNSS receiver's NMEA 0183 log: its fixes and heading as a pose stream."""
