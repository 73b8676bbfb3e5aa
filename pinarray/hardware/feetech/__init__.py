"""Feetech STS bus servos: the protocol, the driver, bring-up and a byte-faithful simulator."""
