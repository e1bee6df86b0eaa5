"""Road files read and checked: the points of a CSV, GeoJSON or OpenDRIVE road within bounds, and the smoothed curve
through them, refused in one line naming the file and the place before anything is built or written."""
