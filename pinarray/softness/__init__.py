"""softness"""
