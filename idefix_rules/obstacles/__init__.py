"""obstacles"""
