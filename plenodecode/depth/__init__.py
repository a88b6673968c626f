"""plenodecode.depth"""
