"""Hobby PWM servos on a PCA9685 board: the second family behind the array-driver seam."""
