"""Pin arrays of each hardware family behind one seam (`pinarray.hardware.driver`)."""
