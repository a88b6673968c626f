"""plenodecode.decode"""
