"""plenodecode.render"""
